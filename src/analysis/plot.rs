//! Figures: curves with shaded 95 % confidence bands, one panel per quantity, as the paper draws them; and
//! estimates per variant with their 95 % confidence intervals (forest plots), for comparing variants.
//! plotters draws the figure as SVG (kept beside the PNG); resvg rasterizes it to PNG with egui's bundled
//! Ubuntu font, so no system font is needed.

use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// One curve: its mean and, where known, the lower and upper ends of its band.
pub(crate) struct Curve {
    pub(crate) label: String,
    pub(crate) x: Vec<f64>,
    pub(crate) mean: Vec<f64>,
    pub(crate) band: Option<(Vec<f64>, Vec<f64>)>,
}

/// One panel of a figure.
impl Curve {
    /// A curve through estimates at `x`: their means, and their 95 % intervals as its band (none where an
    /// estimate has no interval; NaN, not drawn, where there is no estimate).
    pub(crate) fn of_estimates(label: String, x: Vec<f64>, estimates: &[Option<super::stats::Estimate>]) -> Curve {
        let mean: Vec<f64> = estimates.iter().map(|e| e.map_or(f64::NAN, |e| e.mean)).collect();
        let ci: Vec<f64> = estimates.iter().map(|e| e.and_then(|e| e.ci).unwrap_or(0.0)).collect();
        let band =
            (mean.iter().zip(&ci).map(|(m, c)| m - c).collect(), mean.iter().zip(&ci).map(|(m, c)| m + c).collect());
        Curve { label, x, mean, band: Some(band) }
    }
}

pub(crate) struct Panel {
    pub(crate) title: String,
    pub(crate) x_label: String,
    pub(crate) y_label: String,
    pub(crate) curves: Vec<Curve>,
    /// Values to read the curves against, dashed: the paper's and chance's.
    pub(crate) levels: Vec<Level>,
}

/// A value drawn as a dashed line: over `x` (a span of the x axis, e.g. the paper's start over the
/// first episodes and its end over the last 100), or across the panel when None.
pub(crate) struct Level {
    pub(crate) label: String,
    pub(crate) y: f64,
    pub(crate) x: Option<(f64, f64)>,
    /// Chance (grey, thin) or a stated value (in the colour of the curve it is about: `colour`, the
    /// curve's index).
    pub(crate) chance: bool,
    pub(crate) colour: usize,
}

/// One row of an [`EstimatePanel`]: a variant's mean over seeds and the half-width of its 95 % CI (None
/// with one seed; a mean of NaN when the variant has no run yet).
pub(crate) struct Row {
    pub(crate) label: String,
    pub(crate) mean: f64,
    pub(crate) ci: Option<f64>,
}

/// A panel of estimates, one row per variant, top to bottom, against a line at zero: which variants
/// change a quantity, and whether the change is outside the 95 % CI. The first row's interval is shaded
/// across the panel: the base the other variants are read against.
pub(crate) struct EstimatePanel {
    pub(crate) title: String,
    pub(crate) x_label: String,
    pub(crate) rows: Vec<Row>,
}

/// A matrix of values drawn as coloured cells (cross-play: rows the prey's snapshots, columns the
/// predators'), row 0 at the bottom, on the viridis scale from its smallest value to its largest.
pub(crate) struct Heatmap {
    pub(crate) title: String,
    pub(crate) x_label: String,
    pub(crate) y_label: String,
    /// The column labels (one per column) and the row labels (one per row).
    pub(crate) x_ticks: Vec<String>,
    pub(crate) y_ticks: Vec<String>,
    /// `values[row][column]`; a value that is not finite is a grey cell (no value).
    pub(crate) values: Vec<Vec<f64>>,
    /// Colour by log(1 + value) (counts spanning orders of magnitude, as catches against untrained prey).
    pub(crate) log: bool,
    /// Colour a signed value: blue below zero, white at zero, red above, on a scale symmetric about zero
    /// (a turn to the right or to the left), instead of viridis from the smallest value to the largest.
    pub(crate) diverging: bool,
    /// Cells drawn crossed out (`marked[row][column]`; empty for none): a grid's cells whose interval
    /// does not decide (`grid_figures`).
    pub(crate) marked: Vec<Vec<bool>>,
    /// Each cell's value written in it (two decimals): small maps, as a grid's.
    pub(crate) annotate: bool,
}

impl Heatmap {
    /// A map over a focal agent's body frame (`analysis::response`, `analysis::force_map`): columns
    /// ahead, rows to the left, both at `centres` (metres), `values[row][column]`.
    pub(crate) fn body_frame(title: String, centres: &[f64], values: &[Vec<f64>], diverging: bool) -> Heatmap {
        let ticks: Vec<String> = centres.iter().map(|c| format!("{c:.2}")).collect();
        Heatmap {
            title,
            x_label: "ahead (m)".into(),
            y_label: "to the left (m)".into(),
            x_ticks: ticks.clone(),
            y_ticks: ticks,
            values: values.to_vec(),
            log: false,
            diverging,
            marked: Vec::new(),
            annotate: false,
        }
    }
}

/// Size in pixels of one heat map (panels side by side).
pub(crate) const HEATMAP_SIZE: (u32, u32) = (560, 520);

/// Size in pixels of one panel of curves (panels side by side).
pub(crate) const PANEL_SIZE: (u32, u32) = (640, 420);
/// Width in pixels of one estimates panel, and height per row (panels two to a row).
const ESTIMATE_PANEL_WIDTH: u32 = 600;
const ESTIMATE_ROW_HEIGHT: u32 = 34;

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

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

/// The figure as SVG text: `panels` drawn by `draw` on a grid of `columns` columns of `cell`-sized cells.
fn figure<P>(
    panels: &[P],
    columns: usize,
    cell: (u32, u32),
    draw: &dyn Fn(&P, &Area) -> crate::error::Result<()>,
) -> crate::error::Result<String> {
    let columns = columns.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(columns).max(1);
    let mut text = String::new();
    {
        let size = (cell.0 * columns as u32, cell.1 * rows as u32);
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        for (panel, area) in panels.iter().zip(root.split_evenly((rows, columns))) {
            draw(panel, &area)?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(without_repeated_points(&text))
}

/// plotters writes every point of a curve at whole pixels, so a 2000-episode curve on a ~500-pixel axis
/// repeats points; a segment from a point to itself draws nothing, so each polyline and polygon keeps
/// one point of every run of repeats (a fifth of the committed SVG bytes).
fn without_repeated_points(svg: &str) -> String {
    const POINTS: &str = " points=\"";
    let mut out = String::with_capacity(svg.len());
    let mut rest = svg;
    while let Some(at) = rest.find(POINTS) {
        let start = at + POINTS.len();
        out.push_str(&rest[..start]);
        let end = rest[start..].find('"').map_or(rest.len(), |e| start + e);
        let mut last = None;
        let kept: Vec<&str> = rest[start..end]
            .split(' ')
            .filter(|p| {
                let new = last != Some(*p);
                last = Some(*p);
                new
            })
            .collect();
        out.push_str(&kept.join(" "));
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// A figure of curves, its panels side by side, as SVG text.
pub(crate) fn svg(panels: &[Panel]) -> crate::error::Result<String> {
    figure(panels, panels.len(), PANEL_SIZE, &draw_panel)
}

/// A figure of estimates, two panels to a row, as SVG text.
fn estimates_svg(panels: &[EstimatePanel]) -> crate::error::Result<String> {
    let rows = panels.iter().map(|p| p.rows.len()).max().unwrap_or(1) as u32;
    figure(panels, 2, (ESTIMATE_PANEL_WIDTH, (90 + ESTIMATE_ROW_HEIGHT * rows).max(240)), &draw_estimates)
}

fn draw_estimates(panel: &EstimatePanel, area: &Area) -> crate::error::Result<()> {
    use plotters::coord::ranged1d::SegmentValue;
    let n = panel.rows.len();
    let ci = |r: &Row| r.ci.unwrap_or(0.0);
    // The axis always holds zero (the line every change is judged against) and every interval.
    let ends = panel.rows.iter().flat_map(|r| [r.mean - ci(r), r.mean + ci(r)]).filter(|v| v.is_finite());
    let (lo, hi) = ends.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let pad = 0.08 * (hi - lo).max(1e-3);
    let label = |v: &SegmentValue<i32>| match v {
        // Row 0 on top: plotters counts up from the bottom.
        SegmentValue::CenterOf(k) if (*k as usize) < n => panel.rows[n - 1 - *k as usize].label.clone(),
        _ => String::new(),
    };
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 17))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(200)
        // A segmented range of 0..k holds k + 1 segments, one per row here.
        .build_cartesian_2d((lo - pad)..(hi + pad), (0..(n as i32 - 1).max(0)).into_segmented())
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .label_style(("sans-serif", 13))
        .y_labels(n)
        .y_label_formatter(&label)
        .x_label_formatter(&tick)
        .disable_y_mesh()
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(draw_err)?;
    let zero = [(0.0, SegmentValue::Exact(0)), (0.0, SegmentValue::Last)];
    chart.draw_series(LineSeries::new(zero, BLACK.mix(0.5).stroke_width(1))).map_err(draw_err)?;
    if let Some(base) = panel.rows.first().filter(|r| r.mean.is_finite() && r.ci.is_some()) {
        let band = [(base.mean - ci(base), SegmentValue::Exact(0)), (base.mean + ci(base), SegmentValue::Last)];
        chart.draw_series(std::iter::once(Rectangle::new(band, COLOURS[0].mix(0.12).filled()))).map_err(draw_err)?;
    }
    let bars = panel.rows.iter().enumerate().filter(|(_, r)| r.mean.is_finite()).map(|(i, r)| {
        let colour = COLOURS[i % COLOURS.len()];
        ErrorBar::new_horizontal(
            SegmentValue::CenterOf((n - 1 - i) as i32),
            r.mean - ci(r),
            r.mean,
            r.mean + ci(r),
            colour.filled().stroke_width(2),
            10,
        )
    });
    chart.draw_series(bars).map_err(draw_err)?;
    Ok(())
}

/// Viridis at `t` in [0, 1], interpolated between five of its colours (perceptually ordered, readable in
/// grey and by colour-blind readers).
fn viridis(t: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 5] =
        [(68.0, 1.0, 84.0), (59.0, 82.0, 139.0), (33.0, 145.0, 140.0), (94.0, 201.0, 98.0), (253.0, 231.0, 37.0)];
    let x = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - k as f64;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    let mix = |p: f64, q: f64| (p + f * (q - p)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Blue (−1) through white (0) to red (+1).
fn diverging(t: f64) -> RGBColor {
    let t = t.clamp(-1.0, 1.0);
    let (end, f) = if t < 0.0 { ((33.0, 102.0, 172.0), -t) } else { ((178.0, 24.0, 43.0), t) };
    let mix = |q: f64| (255.0 + f * (q - 255.0)).round() as u8;
    RGBColor(mix(end.0), mix(end.1), mix(end.2))
}

fn draw_heatmap(map: &Heatmap, area: &Area) -> crate::error::Result<()> {
    use plotters::coord::ranged1d::SegmentValue;
    let (rows, columns) = (map.values.len(), map.values.first().map_or(0, Vec::len));
    let finite = map.values.iter().flatten().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    let scale = if map.log { ", log colour" } else { "" };
    let title = match lo.is_finite() {
        true => format!(
            "{}: {} (dark) to {}{scale}",
            map.title,
            tick(&((lo * 1e3).round() / 1e3)),
            tick(&((hi * 1e3).round() / 1e3))
        ),
        false => format!("{}: no values", map.title),
    };
    let title = match (map.diverging, lo.is_finite()) {
        (true, true) => format!("{title}; blue < 0 < red"),
        _ => title,
    };
    let shade = |v: f64| if map.log { v.max(0.0).ln_1p() } else { v };
    let (lo, hi) = (shade(lo), shade(hi));
    let reach = lo.abs().max(hi.abs());
    // Labels on about eight rows and columns, whatever the matrix' size.
    let every = |n: usize| n.div_ceil(8).max(1);
    let label = |ticks: &[String], n: usize| {
        let ticks = ticks.to_vec();
        move |v: &SegmentValue<i32>| match v {
            SegmentValue::CenterOf(k) if (*k as usize) < n && (*k as usize).is_multiple_of(every(n)) => {
                ticks[*k as usize].clone()
            }
            _ => String::new(),
        }
    };
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 14))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(56)
        .build_cartesian_2d(
            (0..(columns as i32 - 1).max(0)).into_segmented(),
            (0..(rows as i32 - 1).max(0)).into_segmented(),
        )
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(&map.x_label)
        .y_desc(&map.y_label)
        .label_style(("sans-serif", 12))
        .x_labels(columns)
        .y_labels(rows)
        .x_label_formatter(&label(&map.x_ticks, columns))
        .y_label_formatter(&label(&map.y_ticks, rows))
        .disable_mesh()
        .draw()
        .map_err(draw_err)?;
    let edge = |k: usize, n: usize| if k >= n { SegmentValue::Last } else { SegmentValue::Exact(k as i32) };
    let cells = map.values.iter().enumerate().flat_map(|(i, row)| {
        row.iter().enumerate().map(move |(j, &v)| {
            let colour = match (v.is_finite(), map.diverging) {
                (true, false) => viridis(if hi > lo { (shade(v) - lo) / (hi - lo) } else { 0.5 }),
                (true, true) => diverging(if reach > 0.0 { v / reach } else { 0.0 }),
                (false, _) => RGBColor(200, 200, 200),
            };
            Rectangle::new(
                [(edge(j, columns), edge(i, rows)), (edge(j + 1, columns), edge(i + 1, rows))],
                colour.filled(),
            )
        })
    });
    chart.draw_series(cells).map_err(draw_err)?;
    let marked = |i: usize, j: usize| map.marked.get(i).and_then(|r| r.get(j)).copied().unwrap_or(false);
    for (i, row) in map.values.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            if marked(i, j) {
                let (a, b) = ((edge(j, columns), edge(i, rows)), (edge(j + 1, columns), edge(i + 1, rows)));
                let (c, d) = ((edge(j, columns), edge(i + 1, rows)), (edge(j + 1, columns), edge(i, rows)));
                let style = WHITE.mix(0.8).stroke_width(2);
                chart
                    .draw_series([PathElement::new(vec![a, b], style), PathElement::new(vec![c, d], style)])
                    .map_err(draw_err)?;
            }
            if map.annotate && v.is_finite() {
                let at = (SegmentValue::CenterOf(j as i32), SegmentValue::CenterOf(i as i32));
                let text = format!("{v:.2}");
                // White on viridis' dark half and on the diverging scale's strong ends, black elsewhere.
                let dark = match map.diverging {
                    false => hi > lo && (shade(v) - lo) / (hi - lo) < 0.55,
                    true => reach > 0.0 && (v / reach).abs() > 0.6,
                };
                let ink = if dark { WHITE } else { BLACK };
                let style = ("sans-serif", 13).into_font().color(&ink).pos(plotters::style::text_anchor::Pos::new(
                    plotters::style::text_anchor::HPos::Center,
                    plotters::style::text_anchor::VPos::Center,
                ));
                chart.draw_series([Text::new(text, at, style)]).map_err(draw_err)?;
            }
        }
    }
    Ok(())
}

/// Writes heat maps side by side as `stem.svg` and `stem.png` (atomically, replacing earlier figures).
pub(crate) fn save_heatmaps(stem: &Path, maps: &[Heatmap]) -> crate::error::Result<()> {
    save_heatmaps_in(stem, maps, maps.len())
}

/// [`save_heatmaps`], `columns` to a row.
pub(crate) fn save_heatmaps_in(stem: &Path, maps: &[Heatmap], columns: usize) -> crate::error::Result<()> {
    write(stem, figure(maps, columns, HEATMAP_SIZE, &draw_heatmap)?)
}

/// A tick value as plotters would print it, without the "-0.0" of a rounding error.
fn tick(x: &f64) -> String {
    let v = (x * 1e9).round() / 1e9;
    if v == 0.0 {
        "0".into()
    } else {
        v.to_string()
    }
}

fn draw_panel(panel: &Panel, area: &Area) -> crate::error::Result<()> {
    let finite = |v: &&f64| v.is_finite();
    let xs = panel.curves.iter().flat_map(|c| c.x.iter()).filter(finite);
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    // The axis fits the mean curves with room around them; bands (wide with few seeds) are clipped to it.
    let means = panel.curves.iter().flat_map(|c| c.mean.iter());
    let (m0, m1) = means.filter(finite).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| (a.min(y), b.max(y)));
    let bands = panel.curves.iter().flat_map(|c| c.band.iter().flat_map(|(lo, hi)| lo.iter().chain(hi.iter())));
    let (b0, b1) = bands.filter(finite).fold((m0, m1), |(a, b), &y| (a.min(y), b.max(y)));
    // The axis holds every level too: a paper's value the curves never reach is the point of drawing it.
    let levels = panel.levels.iter().map(|l| &l.y);
    let (m0, m1) = levels.filter(finite).fold((m0, m1), |(a, b), &y| (a.min(y), b.max(y)));
    let (b0, b1) = (b0.min(m0), b1.max(m1));
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
        .label_style(("sans-serif", 15))
        // Episodes and steps as integers; an axis spanning a few units (a grid's positions) with decimals.
        .x_label_formatter(&|x| if x1 - x0 < 5.0 { format!("{x:.2}") } else { format!("{x:.0}") })
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(draw_err)?;
    for (i, c) in panel.curves.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        if let Some((lo, hi)) = &c.band {
            let upper = c.x.iter().zip(hi).map(|(&x, &y)| (x, y));
            let lower = c.x.iter().zip(lo).rev().map(|(&x, &y)| (x, y));
            let outline: Vec<(f64, f64)> =
                upper.chain(lower).filter(|p| p.1.is_finite()).map(|(x, y)| (x, y.clamp(y0, y1))).collect();
            chart.draw_series(std::iter::once(Polygon::new(outline, colour.mix(0.2).filled()))).map_err(draw_err)?;
        }
        let points = c.x.iter().zip(&c.mean).map(|(&x, &y)| (x, y)).filter(|p| p.1.is_finite());
        chart
            .draw_series(LineSeries::new(points, colour.stroke_width(2)))
            .map_err(draw_err)?
            .label(c.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
    }
    // Each kind of level once in the legend.
    let mut named = [false; 2];
    for l in panel.levels.iter().filter(|l| l.y.is_finite()) {
        let style = match l.chance {
            true => BLACK.mix(0.45).stroke_width(1),
            false => COLOURS[l.colour % COLOURS.len()].stroke_width(3),
        };
        let (a, b) = l.x.unwrap_or((x0, x1));
        let series = chart
            .draw_series(DashedLineSeries::new([(a.max(x0), l.y), (b.min(x1), l.y)], 6, 4, style))
            .map_err(draw_err)?;
        if !std::mem::replace(&mut named[usize::from(l.chance)], true) {
            series.label(l.label.clone()).legend(move |(x, y)| {
                plotters::element::DashedPathElement::new(vec![(x, y), (x + 18, y)], 5, 3, style)
            });
        }
    }
    let entries = panel.curves.len() + named.iter().filter(|&&n| n).count();
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 14))
        .position(legend_corner(panel, (x0, x1), (y0, y1), entries))
        .draw()
        .map_err(draw_err)?;
    Ok(())
}

/// Where a panel's legend covers the least of its data: the upper right corner unless curves or levels
/// pass there, else the corner with the fewest points under the box the legend takes (about a third of
/// the width, and a line of 8 % of the height per entry).
fn legend_corner(panel: &Panel, (x0, x1): (f64, f64), (y0, y1): (f64, f64), entries: usize) -> SeriesLabelPosition {
    let (w, h) = (0.36 * (x1 - x0), (0.08 * entries as f64 + 0.04).min(0.9) * (y1 - y0));
    let covered = |right: bool, top: bool| {
        let (bx0, bx1) = if right { (x1 - w, x1) } else { (x0, x0 + w) };
        let (by0, by1) = if top { (y1 - h, y1) } else { (y0, y0 + h) };
        let inside = |x: f64, y: f64| (bx0..=bx1).contains(&x) && (by0..=by1).contains(&y);
        let points = panel.curves.iter().flat_map(|c| c.x.iter().zip(&c.mean)).filter(|(&x, &y)| inside(x, y)).count();
        // A level line across the box counts as many points as it would take to cross it.
        let levels = panel.levels.iter().filter(|l| (by0..=by1).contains(&l.y)).count() * 50;
        points + levels
    };
    let corners = [
        (true, true, SeriesLabelPosition::UpperRight),
        (false, true, SeriesLabelPosition::UpperLeft),
        (true, false, SeriesLabelPosition::LowerRight),
        (false, false, SeriesLabelPosition::LowerLeft),
    ];
    if covered(true, true) == 0 {
        return SeriesLabelPosition::UpperRight;
    }
    corners.into_iter().min_by_key(|&(right, top, _)| covered(right, top)).map(|c| c.2).expect("four corners")
}

/// Rasterizes SVG text to PNG bytes.
pub(crate) fn png(svg: &str) -> crate::error::Result<Vec<u8>> {
    Ok(crate::svg::rasterize(svg, &crate::svg::options())?.encode_png().map_err(draw_err)?)
}

/// Writes a figure of curves as `stem.svg` and `stem.png` (atomically, replacing earlier figures).
pub(crate) fn save(stem: &Path, panels: &[Panel]) -> crate::error::Result<()> {
    write(stem, svg(panels)?)
}

/// [`save`], `columns` panels to a row.
pub(crate) fn save_in(stem: &Path, panels: &[Panel], columns: usize) -> crate::error::Result<()> {
    write(stem, figure(panels, columns, PANEL_SIZE, &draw_panel)?)
}

/// Writes a figure of estimates as `stem.svg` and `stem.png` (atomically, replacing earlier figures).
pub(crate) fn save_estimates(stem: &Path, panels: &[EstimatePanel]) -> crate::error::Result<()> {
    write(stem, estimates_svg(panels)?)
}

fn write(stem: &Path, text: String) -> crate::error::Result<()> {
    let bytes = png(&text)?;
    let [svg, png] = files(stem);
    crate::io::write_file(&svg, crate::io::Existing::Replace, text.as_bytes())?;
    crate::io::write_file(&png, crate::io::Existing::Replace, &bytes)
}

/// The files a figure saved as `stem` is written to: its SVG and a PNG beside it.
pub(crate) fn files(stem: &Path) -> [PathBuf; 2] {
    // Appended, not `with_extension`: a stem with a dot in its name (`exp.v2-force-map-prey-prey`) keeps it.
    let with = |ending: &str| {
        let mut name = stem.as_os_str().to_owned();
        name.push(ending);
        PathBuf::from(name)
    };
    [with(".svg"), with(".png")]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_points_are_dropped_and_nothing_else_changes() {
        let svg = r##"<polyline stroke="#000" points="1,2 1,2 1,2 3,4 1,2 5,6 5,6 "/><text x="1">1,2 1,2</text>"##;
        let kept = without_repeated_points(svg);
        assert_eq!(kept, r##"<polyline stroke="#000" points="1,2 3,4 1,2 5,6 "/><text x="1">1,2 1,2</text>"##);
        assert_eq!(without_repeated_points(&kept), kept);
    }

    /// Runs of one colour along a line of pixels, ignoring white and the grey of axes and text.
    fn coloured_runs(pixels: impl Iterator<Item = [u8; 3]>) -> usize {
        let (mut runs, mut last) = (0, None);
        for p in pixels {
            let grey = p[0].abs_diff(p[1]) < 8 && p[1].abs_diff(p[2]) < 8;
            let current = (!grey).then_some(p);
            if current.is_some() && current != last {
                runs += 1;
            }
            last = current;
        }
        runs
    }

    #[test]
    fn a_heat_map_draws_one_cell_per_value() {
        let (rows, columns) = (3, 4);
        let map = Heatmap {
            title: "test".into(),
            x_label: "column".into(),
            y_label: "row".into(),
            x_ticks: (0..columns).map(|j| (100 * j).to_string()).collect(),
            y_ticks: (0..rows).map(|i| (100 * i).to_string()).collect(),
            values: (0..rows).map(|i| (0..columns).map(|j| (i * columns + j) as f64).collect()).collect(),
            log: false,
            diverging: false,
            marked: Vec::new(),
            annotate: false,
        };
        let dir = tempfile::tempdir().unwrap();
        let stem = dir.path().join("map");
        save_heatmaps(&stem, &[map]).unwrap();
        let png = resvg::tiny_skia::Pixmap::decode_png(&std::fs::read(stem.with_extension("png")).unwrap()).unwrap();
        assert_eq!((png.width(), png.height()), HEATMAP_SIZE);
        let pixel = |x: u32, y: u32| {
            let p = png.pixel(x, y).unwrap();
            [p.red(), p.green(), p.blue()]
        };
        // Through the middle of the plot area: one run of colour per column, one per row.
        let (w, h) = HEATMAP_SIZE;
        assert_eq!(coloured_runs((0..w).map(|x| pixel(x, h / 2))), columns);
        assert_eq!(coloured_runs((0..h).map(|y| pixel(w / 2 + 20, y))), rows);
        assert!(std::fs::read_to_string(stem.with_extension("svg")).unwrap().contains("test: 0 (dark) to 11"));
    }

    #[test]
    fn ticks_read_as_written_without_a_negative_zero() {
        assert_eq!(tick(&-1.3877787807814457e-17), "0");
        assert_eq!(tick(&(0.1 + 0.2)), "0.3");
        assert_eq!(tick(&-0.05), "-0.05");
    }
}
