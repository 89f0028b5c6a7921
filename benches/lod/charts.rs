//! The lod bench's charts: time against the largest error, log-log, one per pass.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::coord::combinators::LogCoord;
use plotters::prelude::*;
use serde_json::Value;

use crate::common::write;

/// Where the charts draw errors of 0 (the exact layer against itself): log axes have no 0.
pub const FLOOR: f64 = 1e-7;

/// Chart size in pixels (the SVG's too).
pub const CHART: (u32, u32) = (1280, 860);

/// Colour and legend name of each family, in legend order.
pub const FAMILIES: [(&str, RGBColor); 7] = [
    ("exact", RGBColor(0, 0, 0)),
    ("env", RGBColor(31, 119, 180)),
    ("env+keep", RGBColor(23, 190, 207)),
    ("table", RGBColor(44, 160, 44)),
    ("table+env", RGBColor(255, 127, 14)),
    ("cull", RGBColor(200, 160, 0)),
    ("peer", RGBColor(148, 103, 189)),
];
/// Tolerance lines and the marks of their choices, in `--tols` order.
pub const TOL_COLOURS: [RGBColor; 4] = [
    RGBColor(214, 39, 40),
    RGBColor(227, 119, 194),
    RGBColor(140, 86, 75),
    RGBColor(188, 189, 34),
];

/// A point of a chart.
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub family: &'static str,
    /// Peers: which.
    pub label: String,
    /// The tolerance that chose it.
    pub tol: Option<f64>,
}

/// The points of one pass: x = median seconds, y = the largest error (fwd: the image's;
/// fb: the largest of the image's and the gradients'), at least [`FLOOR`].
pub fn points(records: &[Value], pass: &str) -> Vec<Point> {
    records
        .iter()
        .filter(|r| r["pass"] == pass)
        .filter_map(|r| {
            let x = r["median_s"].as_f64()?;
            let y = if pass == "fwd" {
                r["errors"]["image"]["max"].as_f64()?
            } else {
                r["err_max"].as_f64()?
            };
            let method = r["method"].as_str().unwrap_or("");
            let family = FAMILIES
                .iter()
                .map(|f| f.0)
                .find(|f| *f == r["family"].as_str().unwrap_or(""))?;
            (x > 0.0 && x.is_finite() && y.is_finite()).then(|| Point {
                x,
                y: y.max(FLOOR),
                family,
                label: method.trim_start_matches("peer-").to_string(),
                tol: r["tol"].as_f64(),
            })
        })
        .collect()
}

/// A chart with log axes on both sides.
pub type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// Runs `$body` with `$s` bound to a closure that makes the marker of `$family` at (0, 0)
/// (pixel offsets), `$h` pixels from its centre to its edge, in colour `$c`: each family's
/// marker is its own type.
macro_rules! with_marker {
    ($family:expr, $h:expr, $c:expr, $s:ident => $body:expr) => {{
        let (h, c): (i32, RGBColor) = ($h, $c);
        match $family {
            "exact" => {
                let $s = || Cross::new((0, 0), h + 1, c.stroke_width(2));
                $body
            }
            "env" => {
                let $s = || Circle::new((0, 0), h, c.filled());
                $body
            }
            "env+keep" => {
                let $s = || TriangleMarker::new((0, 0), h + 1, c.filled());
                $body
            }
            "table" => {
                let $s = || Rectangle::new([(-h, -h), (h, h)], c.filled());
                $body
            }
            "table+env" => {
                let $s = || {
                    Polygon::new(
                        vec![(0, -h - 1), (h + 1, 0), (0, h + 1), (-h - 1, 0)],
                        c.filled(),
                    )
                };
                $body
            }
            "cull" => {
                let $s = || TriangleMarker::new((0, 0), h + 2, c.stroke_width(2));
                $body
            }
            // a tolerance's choice: a ring
            "ring" => {
                let $s = || Circle::new((0, 0), h, c.stroke_width(2));
                $body
            }
            // peers: a hollow square
            _ => {
                let $s = || Rectangle::new([(-h, -h), (h, h)], c.stroke_width(2));
                $body
            }
        }
    }};
}

/// A legend entry: marker (family, half size, colour) and text.
pub type Entry = ((&'static str, i32, RGBColor), String);

/// Draws one pass's chart on `root`: the plot, a legend beside it, a note below.
pub fn draw_chart<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    pass: &str,
    pts: &[Point],
    tols: &[f64],
    note: &str,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (main, foot) = root.split_vertically(CHART.1 - 30);
    let (plot, side) = main.split_horizontally(CHART.0 - 340);
    let (mut x0, mut x1) = pts.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.x), b.max(p.x))
    });
    if !(x0.is_finite() && x1 > 0.0) {
        (x0, x1) = (1e-3, 1.0);
    }
    let (x0, x1) = (x0 / 1.6, x1 * 1.6);
    let y1 = pts
        .iter()
        .map(|p| p.y)
        .chain(tols.iter().copied())
        .fold(1e-2, f64::max);
    let (y0, y1) = (FLOOR / 3.0, y1 * 3.0);
    let (what, y_desc) = if pass == "fwd" {
        ("forward (lod::render)", "max |I - I_exact| / max |I_exact|")
    } else {
        (
            "forward + backward (lod::render + lod::backward)",
            "largest max relative error: image, d_env, d_normals, d_ctrl",
        )
    };
    let mut chart = ChartBuilder::on(&plot)
        .caption(format!("matedit lod: {what}"), ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(46)
        .y_label_area_size(74)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("median time (s)")
        .y_desc(y_desc)
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(236, 236, 236))
        .draw()
        .map_err(e)?;
    let entries = draw_points(&mut chart, pts, tols, (x0, x1)).map_err(e)?;
    for (k, ((family, h, c), text)) in entries.iter().enumerate() {
        let (x, y) = (16, 60 + 24 * k as i32);
        if *h > 0 {
            with_marker!(*family, *h, *c, m => side.draw(&(EmptyElement::at((x, y)) + m())))
                .map_err(e)?;
        }
        side.draw(&Text::new(
            text.as_str(),
            (x + 16, y - 7),
            ("sans-serif", 14),
        ))
        .map_err(e)?;
    }
    foot.draw(&Text::new(
        note,
        (20, 6),
        ("sans-serif", 13).into_font().color(&RGBColor(80, 80, 80)),
    ))
    .map_err(e)?;
    root.present().map_err(e)
}

/// The points and the tolerance lines: the legend's entries.
pub fn draw_points<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    pts: &[Point],
    tols: &[f64],
    (x0, x1): (f64, f64),
) -> Result<Vec<Entry>, DrawingAreaErrorKind<DB::ErrorType>>
where
    DB::ErrorType: 'static,
{
    let mut entries: Vec<Entry> = Vec::new();
    for (i, &t) in tols.iter().enumerate() {
        let c = TOL_COLOURS[i % TOL_COLOURS.len()];
        chart.draw_series(DashedLineSeries::new(
            [(x0, t), (x1, t)],
            8,
            5,
            c.stroke_width(1),
        ))?;
        chart.draw_series(std::iter::once(Text::new(
            format!("tol {t:.0e}"),
            (x0 * 1.08, t * 1.3),
            ("sans-serif", 13).into_font().color(&c),
        )))?;
    }
    let mut draw = |family: &'static str, xy: Vec<(f64, f64)>, h: i32, c: RGBColor| {
        with_marker!(family, h, c, m => chart.draw_series(
            xy.iter().map(|&p| EmptyElement::at(p) + m())
        ).map(|_| ()))
    };
    for &(family, c) in &FAMILIES {
        let of: Vec<&Point> = pts
            .iter()
            .filter(|p| p.family == family && p.tol.is_none())
            .collect();
        // peers: one colour each
        let mut names: Vec<&str> = of.iter().map(|p| p.label.as_str()).collect();
        names.sort();
        names.dedup();
        // a family only a tolerance chose still gets its legend entry
        if names.is_empty() && pts.iter().any(|p| p.family == family) {
            entries.push(((family, 3, c), family.to_string()));
        }
        for (k, name) in names.iter().enumerate() {
            let xy: Vec<(f64, f64)> = of
                .iter()
                .filter(|p| family != "peer" || p.label == *name)
                .map(|p| (p.x, p.y))
                .collect();
            let (text, c, h) = match family {
                "peer" => (
                    format!("peer {name} (error vs our exact)"),
                    if k == 0 { c } else { RGBColor(127, 127, 127) },
                    5,
                ),
                "exact" => (format!("exact (error 0: drawn at {FLOOR:.0e})"), c, 4),
                _ => (family.to_string(), c, 3),
            };
            draw(family, xy, h, c)?;
            entries.push(((family, h, c), text));
            if family != "peer" {
                break;
            }
        }
    }
    // the tolerance runs: their choice's marker inside a ring of the tolerance's colour
    for (i, &t) in tols.iter().enumerate() {
        let c = TOL_COLOURS[i % TOL_COLOURS.len()];
        let of: Vec<&Point> = pts.iter().filter(|p| p.tol == Some(t)).collect();
        if of.is_empty() {
            continue;
        }
        draw("ring", of.iter().map(|p| (p.x, p.y)).collect(), 9, c)?;
        for &(family, _) in &FAMILIES {
            let xy: Vec<(f64, f64)> = of
                .iter()
                .filter(|p| p.family == family)
                .map(|p| (p.x, p.y))
                .collect();
            draw(family, xy, 3, c)?;
        }
        entries.push((("ring", 7, c), format!("chosen for tol {t:.0e}")));
    }
    if entries.iter().any(|((f, ..), _)| *f == "ring") {
        entries.push((("none", 0, WHITE), "(its time includes the choice)".into()));
    }
    Ok(entries)
}

/// Registers the font the charts' text is drawn with: Hack (MIT / Bitstream Vera
/// license), as epaint_default_fonts ships it, so that no system font is needed.
pub fn register_font() -> Result<(), String> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::HACK_REGULAR,
    )
    .map_err(|_| "the embedded font cannot be read".to_string())
}

/// lod_fwd.{png,svg} and lod_fb.{png,svg} in `dir`, from the records: their paths.
pub fn charts(records: &[Value], tols: &[f64], dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut written = Vec::new();
    for pass in ["fwd", "fb"] {
        let pts = points(records, pass);
        let caption = format!(
            "{} points: each method on each scene (normals x env map x material), fast CPU path; \
             errors against the exact layer on the same path",
            pts.len()
        );
        let svg = dir.join(format!("lod_{pass}.svg"));
        {
            let root = SVGBackend::new(&svg, CHART).into_drawing_area();
            draw_chart(&root, pass, &pts, tols, &caption)?;
        }
        let png = dir.join(format!("lod_{pass}.png"));
        let (w, h) = (CHART.0 as usize, CHART.1 as usize);
        let mut buf = vec![0u8; w * h * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buf, CHART).into_drawing_area();
            draw_chart(&root, pass, &pts, tols, &caption)?;
        }
        let bytes = matedit::io::png::encode_rgb8(w, h, &buf).map_err(|e| e.to_string())?;
        write(&png, &bytes);
        written.push(png);
        written.push(svg);
    }
    Ok(written)
}
