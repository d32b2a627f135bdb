//! Figures: curves with shaded 95 % confidence bands, one panel per quantity, as the paper draws them.
//! plotters draws the figure as SVG (kept beside the PNG); resvg rasterizes it to PNG with egui's bundled
//! Ubuntu font, so no system font is needed.

use plotters::prelude::*;
use std::path::Path;

/// One curve: its mean and, where known, the lower and upper ends of its band.
pub struct Curve {
    pub label: String,
    pub x: Vec<f64>,
    pub mean: Vec<f64>,
    pub band: Option<(Vec<f64>, Vec<f64>)>,
}

/// One panel of a figure.
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub curves: Vec<Curve>,
}

/// Figure size in pixels (each panel side by side).
pub const PANEL_SIZE: (u32, u32) = (640, 420);

const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn draw_err(e: impl std::fmt::Display) -> String {
    format!("cannot draw the figure: {e}")
}

/// The figure as SVG text.
pub fn svg(panels: &[Panel]) -> Result<String, String> {
    let mut text = String::new();
    {
        let size = (PANEL_SIZE.0 * panels.len() as u32, PANEL_SIZE.1);
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        for (panel, area) in panels.iter().zip(root.split_evenly((1, panels.len()))) {
            draw_panel(panel, &area)?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(text)
}

fn draw_panel(panel: &Panel, area: &DrawingArea<SVGBackend, plotters::coord::Shift>) -> Result<(), String> {
    let finite = |v: &&f64| v.is_finite();
    let xs = panel.curves.iter().flat_map(|c| c.x.iter()).filter(finite);
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    // The axis fits the mean curves with room around them; bands (wide with few seeds) are clipped to it.
    let means = panel.curves.iter().flat_map(|c| c.mean.iter());
    let (m0, m1) = means.filter(finite).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| (a.min(y), b.max(y)));
    let bands = panel.curves.iter().flat_map(|c| c.band.iter().flat_map(|(lo, hi)| lo.iter().chain(hi.iter())));
    let (b0, b1) = bands.filter(finite).fold((m0, m1), |(a, b), &y| (a.min(y), b.max(y)));
    let (x0, x1) = if x0.is_finite() && x1 > x0 { (x0, x1) } else { (0.0, 1.0) };
    let room = if m1 > m0 { m1 - m0 } else { m0.abs().max(0.1) };
    let (y0, y1) = if m0.is_finite() { (b0.max(m0 - room), b1.min(m1 + room)) } else { (0.0, 1.0) };
    let pad = 0.05 * (y1 - y0).max(1e-9);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .label_style(("sans-serif", 13))
        .x_label_formatter(&|x| format!("{x:.0}"))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(draw_err)?;
    for (i, c) in panel.curves.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        if let Some((lo, hi)) = &c.band {
            let upper = c.x.iter().zip(hi).map(|(&x, &y)| (x, y));
            let lower = c.x.iter().zip(lo).rev().map(|(&x, &y)| (x, y));
            let outline: Vec<(f64, f64)> = upper.chain(lower).filter(|p| p.1.is_finite()).map(|(x, y)| (x, y.clamp(y0, y1))).collect();
            chart.draw_series(std::iter::once(Polygon::new(outline, colour.mix(0.2).filled()))).map_err(draw_err)?;
        }
        let points = c.x.iter().zip(&c.mean).map(|(&x, &y)| (x, y)).filter(|p| p.1.is_finite());
        chart
            .draw_series(LineSeries::new(points, colour.stroke_width(2)))
            .map_err(draw_err)?
            .label(c.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(draw_err)?;
    Ok(())
}

/// Rasterizes SVG text to PNG bytes.
pub fn png(svg: &str) -> Result<Vec<u8>, String> {
    crate::svg::rasterize(svg, &crate::svg::options())?.encode_png().map_err(draw_err)
}

/// Writes `stem.svg` and `stem.png` (atomically, replacing earlier figures).
pub fn save(stem: &Path, panels: &[Panel]) -> Result<(), String> {
    let text = svg(panels)?;
    let bytes = png(&text)?;
    for (ext, data) in [("svg", text.as_bytes()), ("png", bytes.as_slice())] {
        crate::io::write_file(&stem.with_extension(ext), crate::io::Existing::Replace, data)?;
    }
    Ok(())
}
