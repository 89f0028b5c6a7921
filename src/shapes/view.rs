//! How a mesh is seen: the image size, the camera, the object's rotation and the margin;
//! and the placement that turns the mesh into camera space, centred and scaled to fill the
//! frame.

use std::str::FromStr;

use super::mesh::{Mesh, V3, dot, scale, sub, unit, widen};
use crate::camera::Camera;
use crate::error::{Result, invalid};
use crate::splitmix::SplitMix;

/// The margin [`View::new`] leaves: this fraction of the frame's half-width (and
/// half-height) stays empty on each side of the object.
pub const DEFAULT_MARGIN: f64 = 0.05;

/// The object's rotation in degrees: first `yaw` about +y, then `pitch` about +x, then
/// `roll` about +z (right-handed, in the camera frame: x right, y up, z towards the viewer).
/// All zero shows the mesh as its file has it, +y up and +z towards the viewer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rotation {
    /// About +y, degrees.
    pub yaw: f64,
    /// About +x, degrees.
    pub pitch: f64,
    /// About +z, degrees.
    pub roll: f64,
}

impl Rotation {
    /// A uniformly random rotation (Haar measure) drawn from `seed`: yaw and roll uniform in
    /// [0, 360), pitch = asin(u) with u uniform in [-1, 1) (the density cos(pitch) that
    /// Tait-Bryan angles need).
    pub fn random(seed: u64) -> Self {
        // a stream of its own, so that a shape drawn from the same seed does not share it
        let mut rng = SplitMix(seed ^ 0xa076_1d64_78bd_642f);
        Rotation {
            yaw: 360.0 * rng.uniform(),
            pitch: (2.0 * rng.uniform() - 1.0).asin().to_degrees(),
            roll: 360.0 * rng.uniform(),
        }
    }

    /// The matrix Rz(roll) Rx(pitch) Ry(yaw), rows first.
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        let (sy, cy) = self.yaw.to_radians().sin_cos();
        let (sp, cp) = self.pitch.to_radians().sin_cos();
        let (sr, cr) = self.roll.to_radians().sin_cos();
        let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
        let rx = [[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]];
        let rz = [[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]];
        mat_mul(rz, mat_mul(rx, ry))
    }

    /// Checks that the angles are finite.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("yaw", self.yaw),
            ("pitch", self.pitch),
            ("roll", self.roll),
        ] {
            if !v.is_finite() {
                return Err(invalid!("rotation: {name} {v} is not a finite angle"));
            }
        }
        Ok(())
    }
}

impl FromStr for Rotation {
    type Err = String;

    /// `YAW,PITCH,ROLL` in degrees, e.g. `30,-15,0`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let [yaw, pitch, roll] = parts[..] else {
            return Err(format!(
                "'{s}' is not YAW,PITCH,ROLL (three angles in degrees)"
            ));
        };
        let angle = |name: &str, v: &str| match v.parse::<f64>() {
            Ok(a) if a.is_finite() => Ok(a),
            _ => Err(format!("{name} '{v}' is not a finite number of degrees")),
        };
        Ok(Rotation {
            yaw: angle("yaw", yaw)?,
            pitch: angle("pitch", pitch)?,
            roll: angle("roll", roll)?,
        })
    }
}

pub(crate) fn mat_mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

pub(crate) fn mat_vec(m: &[[f64; 3]; 3], v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// What the rasteriser draws and how: see [`super::render_normals`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Orthographic, or a pinhole looking down -z ([`Camera::view_dir`] gives each
    /// pixel's w_p, which the normals are turned to face).
    pub camera: Camera,
    /// The object's rotation about the centre of its bounding box.
    pub rotation: Rotation,
    /// Face normals instead of interpolated vertex normals.
    pub flat: bool,
    /// The fraction of the frame's half-width and half-height left empty on each side
    /// (in tan-space under perspective), in [0, 1).
    pub margin: f64,
}

impl View {
    /// A `width` x `height` orthographic view of the unrotated object, smooth normals, the
    /// default margin.
    pub fn new(width: usize, height: usize) -> Self {
        View {
            width,
            height,
            camera: Camera::Orthographic,
            rotation: Rotation::default(),
            flat: false,
            margin: DEFAULT_MARGIN,
        }
    }

    /// Checks the size, the camera, the angles and the margin.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(invalid!(
                "view: size {}x{} is empty",
                self.width,
                self.height
            ));
        }
        self.camera.validate()?;
        self.rotation.validate()?;
        if !(self.margin >= 0.0 && self.margin < 1.0) {
            return Err(invalid!("view: margin {} is outside [0, 1)", self.margin));
        }
        Ok(())
    }

    /// Half the frame's width and height: in camera units at z = 0 (orthographic) or as
    /// tangents of the half angles (perspective).
    pub(crate) fn half_extent(&self) -> (f64, f64) {
        let aspect = self.width as f64 / self.height as f64;
        let t = match self.camera {
            Camera::Orthographic => 1.0,
            Camera::Perspective { fov_y_deg } => (fov_y_deg.to_radians() / 2.0).tan(),
        };
        (t * aspect, t)
    }
}

/// The mesh in camera space: positions rotated, centred and scaled (orthographic) or
/// moved in front of the camera (perspective) so that the image holds it within the
/// margin; vertex normals rotated and normalised ([0, 0, 0] where they have no direction).
pub(crate) struct Placed {
    pub positions: Vec<V3>,
    pub normals: Vec<V3>,
}

/// Places `mesh` (already validated) for `view`.
pub(crate) fn place(mesh: &Mesh, view: &View) -> Result<Placed> {
    let r = view.rotation.matrix();
    let (lo, hi) = mesh.bounds();
    let centre = scale([lo[0] + hi[0], lo[1] + hi[1], lo[2] + hi[2]], 0.5);
    let mut positions: Vec<V3> = mesh
        .positions
        .iter()
        .map(|&p| mat_vec(&r, sub(widen(p), centre)))
        .collect();
    let normals = mesh
        .vertex_normals()
        .iter()
        .map(|&n| unit(mat_vec(&r, widen(n))).unwrap_or([0.0; 3]))
        .collect();
    let used = used_vertices(mesh);
    let (hx, hy) = view.half_extent();
    let (hx, hy) = (hx * (1.0 - view.margin), hy * (1.0 - view.margin));
    match view.camera {
        Camera::Orthographic => {
            let (lo, hi) = bounds_of(&positions, &used, |p| [p[0], p[1]]);
            let (ex, ey) = ((hi[0] - lo[0]) / 2.0, (hi[1] - lo[1]) / 2.0);
            let s = (hx / ex).min(hy / ey);
            if !(s.is_finite() && s > 0.0) {
                return Err(invalid!(
                    "mesh: seen from this direction it has no extent in the image (a line or a point)"
                ));
            }
            let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
            for p in &mut positions {
                *p = [(p[0] - cx) * s, (p[1] - cy) * s, p[2] * s];
            }
        }
        Camera::Perspective { .. } => {
            let radius = used
                .iter()
                .map(|&v| dot(positions[v], positions[v]).sqrt())
                .fold(0.0, f64::max);
            for p in &mut positions {
                *p = scale(*p, 1.0 / radius);
            }
            let offset = fit_perspective(&positions, &used, hx, hy)?;
            for p in &mut positions {
                *p = [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]];
            }
        }
    }
    Ok(Placed { positions, normals })
}

/// The vertices some triangle uses, each once, in order.
fn used_vertices(mesh: &Mesh) -> Vec<usize> {
    let mut seen = vec![false; mesh.positions.len()];
    for tri in &mesh.triangles {
        for &v in tri {
            seen[v as usize] = true;
        }
    }
    (0..seen.len()).filter(|&v| seen[v]).collect()
}

/// The 2D bounding box of `f` over the used vertices.
fn bounds_of(pos: &[V3], used: &[usize], f: impl Fn(V3) -> [f64; 2]) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for &v in used {
        let q = f(pos[v]);
        for k in 0..2 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    (lo, hi)
}

/// Closest the object's bounding sphere (radius 1) may come: its nearest point stays this
/// far in front of the camera.
const NEAREST: f64 = 0.02;

/// The offset that puts a mesh within the unit ball in front of a pinhole camera, its
/// projection centred and as large as the half-extents `hx`, `hy` (tangents) allow.
/// Moving away shrinks the projection, so the distance is found by bisection between the
/// nearest allowed (the ball `NEAREST` in front of the camera) and the distance at which
/// the whole ball fits; at each distance the projection is centred by a few sideways
/// moves of its box's centre times the distance.
fn fit_perspective(pos: &[V3], used: &[usize], hx: f64, hy: f64) -> Result<V3> {
    let no_extent = || {
        invalid!("mesh: seen from this direction it has no extent in the image (a line or a point)")
    };
    // (offset, size of the projection over the frame's) at distance d
    let at = |d: f64| {
        let mut o = [0.0, 0.0];
        let mut k = 0.0f64;
        for _ in 0..8 {
            let mut moved = 0.0f64;
            k = 0.0;
            for (axis, half) in [(0, hx), (1, hy)] {
                // the vertices at either end of the projection on this axis, then the
                // sideways move that puts them at equal and opposite tangents:
                // (xa + o) / wa = -(xb + o) / wb
                let (mut lo, mut hi) = ((f64::INFINITY, 0.0, 1.0), (f64::NEG_INFINITY, 0.0, 1.0));
                for &v in used {
                    let w = d - pos[v][2];
                    let t = (pos[v][axis] + o[axis]) / w;
                    if t < lo.0 {
                        lo = (t, pos[v][axis], w);
                    }
                    if t > hi.0 {
                        hi = (t, pos[v][axis], w);
                    }
                }
                k = k.max((hi.0 - lo.0) / 2.0 / half);
                let next = -(lo.1 * hi.2 + hi.1 * lo.2) / (lo.2 + hi.2);
                moved = moved.max((next - o[axis]).abs());
                o[axis] = next;
            }
            if moved < 1e-12 {
                break;
            }
        }
        ([o[0], o[1], -d], k)
    };
    let half_angle = hx.atan().min(hy.atan());
    let mut far = (1.0 / half_angle.sin()).max(1.0 + NEAREST);
    let mut near = 1.0 + NEAREST;
    let (best, k) = at(near);
    if !(k.is_finite() && k > 0.0) {
        return Err(no_extent());
    }
    if k <= 1.0 {
        return Ok(best);
    }
    // grow `far` until it fits (the centring can move the ball off the axis)
    while at(far).1 > 1.0 {
        far *= 2.0;
        if far > 1e6 {
            return Err(no_extent());
        }
    }
    // to a millionth of the distance: the projection's size to about as much
    while far - near > 1e-6 * far {
        let mid = 0.5 * (near + far);
        if at(mid).1 > 1.0 {
            near = mid;
        } else {
            far = mid;
        }
    }
    Ok(at(far).0)
}
