//! The camera: orthographic (the default) or perspective, and the view direction w_p.

use crate::error::{Result, invalid};

/// How pixels see the scene. See CONVENTIONS "View direction".
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Camera {
    /// w_p = (0, 0, 1) for every pixel.
    #[default]
    Orthographic,
    /// A pinhole camera looking down -z with the given vertical field of view in degrees.
    Perspective {
        /// Vertical field of view, degrees, in (0, 180).
        fov_y_deg: f64,
    },
}

impl Camera {
    /// Checks that the field of view is finite and in (0, 180) degrees.
    pub fn validate(&self) -> Result<()> {
        if let Camera::Perspective { fov_y_deg } = *self
            && !(fov_y_deg.is_finite() && fov_y_deg > 0.0 && fov_y_deg < 180.0)
        {
            return Err(invalid!(
                "camera: field of view {fov_y_deg} degrees is outside (0, 180)"
            ));
        }
        Ok(())
    }

    /// Whether w_p is the same for every pixel (then the half vector, theta_d and the
    /// spline coefficients depend on the texel alone).
    pub fn is_orthographic(&self) -> bool {
        matches!(self, Camera::Orthographic)
    }

    /// The unit vector from the surface point at pixel (x, y) of a `width` x `height`
    /// image towards the camera.
    pub fn view_dir(&self, x: usize, y: usize, width: usize, height: usize) -> [f64; 3] {
        match *self {
            Camera::Orthographic => [0.0, 0.0, 1.0],
            Camera::Perspective { fov_y_deg } => {
                let a = width as f64 / height as f64;
                let t = (fov_y_deg.to_radians() / 2.0).tan();
                let dx = ((x as f64 + 0.5) / width as f64 * 2.0 - 1.0) * t * a;
                let dy = (1.0 - (y as f64 + 0.5) / height as f64 * 2.0) * t;
                let len = (dx * dx + dy * dy + 1.0).sqrt();
                // w_p = -normalize(dx, dy, -1)
                [-dx / len, -dy / len, 1.0 / len]
            }
        }
    }
}
