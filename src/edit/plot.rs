//! The loss curve of a fit as a PNG: loss (log scale) against step.

use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::error::{Error, Result};

const SIZE: (u32, u32) = (640, 400);

fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("loss plot: {e}"))
}

/// Registers the font the plot's text is drawn with: Hack (MIT / Bitstream Vera license),
/// as epaint_default_fonts ships it, so that no system font is needed.
fn register_font() -> Result<()> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::HACK_REGULAR,
    )
    .map_err(|_| plot_error("the embedded font cannot be read"))
}

/// The loss per step, drawn on a log scale, as PNG bytes.
pub fn loss_png(losses: &[f64]) -> Result<Vec<u8>> {
    register_font()?;
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let mut buf = vec![0u8; w * h * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let positive: Vec<(f64, f64)> = losses
            .iter()
            .enumerate()
            .filter(|(_, l)| **l > 0.0 && l.is_finite())
            .map(|(i, &l)| (i as f64, l))
            .collect();
        let lo = positive.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let hi = positive.iter().map(|p| p.1).fold(0.0, f64::max);
        let (lo, hi) = if positive.is_empty() {
            (1e-6, 1.0)
        } else {
            (lo / 1.5, hi * 1.5)
        };
        let steps = (losses.len().max(2) - 1) as f64;
        let mut chart = ChartBuilder::on(&root)
            .caption("fit loss", ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..steps, (lo..hi).log_scale())
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .x_desc("step")
            .y_desc("loss")
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(plot_error)?;
        chart
            .draw_series(LineSeries::new(positive, &BLUE))
            .map_err(plot_error)?;
        root.present().map_err(plot_error)?;
    }
    crate::io::png::encode_rgb8(w, h, &buf)
}

#[cfg(test)]
mod tests {
    #[test]
    fn draws_a_curve() {
        let losses: Vec<f64> = (0..50).map(|i| 1.0 / (1.0 + i as f64)).collect();
        let png = super::loss_png(&losses).expect("plots");
        assert_eq!(&png[1..4], b"PNG");
        // an empty curve still gives a picture
        assert!(super::loss_png(&[]).is_ok());
    }
}
