//! Headless animations: an episode of a simulation drawn to an animated GIF, with no window and no GPU.
//!
//! Each frame is an SVG (agents as in the viewer: a disc of the body radius in the species' colour, a
//! heading line, optional fading trails, catches ringed in red; on the torus a body crossing an edge is
//! also drawn on the opposite side and the arena clips both, so the seam shows no streak), rasterized by
//! [`crate::svg`] (resvg / tiny-skia). The `gif` crate encodes the frames against one fixed palette of
//! the scene's colours and their blends with the floor; pixels unchanged since the previous frame are
//! written transparent, which keeps a 300-step clip of 50 prey around a megabyte.

use crate::io::{AtomicFile, Existing};
use crate::scene::Boundary;
use crate::sim::clock::Episode;
use crate::sim::components::*;
use crate::sim::metrics::SwarmMetrics;
use crate::sim::space::Arena;
use crate::sim::species::SpeciesRegistry;
use crate::sim::Simulation;
use bevy::math::DVec2;
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::{HashMap, VecDeque};
use std::fmt::Write as _;
use std::path::Path;

/// What to draw and how big.
#[derive(Clone, Debug)]
pub struct AnimateOptions {
    /// Environment steps in the clip (one frame per `steps_per_frame` of them, plus the first state).
    pub steps: usize,
    pub steps_per_frame: usize,
    /// Fading trails of the last [`TRAIL_STEPS`] positions.
    pub trails: bool,
    /// Width of the square arena image in pixels; the caption adds [`CAPTION`] below.
    pub size: u32,
    /// First caption line (what is shown: the run or scene).
    pub title: String,
    pub progress: bool,
}

/// Trail length in steps.
pub(crate) const TRAIL_STEPS: usize = 40;
/// Trails fade with age in this many steps of opacity.
const FADE_BANDS: usize = 2;
/// Caption height in pixels.
pub const CAPTION: u32 = 38;
/// The heading line runs from the centre to this many body radii (as in the viewer).
const HEADING_LENGTH: f64 = 1.7;

// Colours, sRGB bytes (the viewer's).
const FLOOR: [u8; 3] = [250, 250, 247];
const OUTSIDE: [u8; 3] = [33, 33, 38];
const TEXT: [u8; 3] = [235, 235, 235];
const WALL: [u8; 3] = [107, 107, 117];
const CATCH: [u8; 3] = [217, 13, 26];

/// What the clip showed, for the caller's summary line.
#[derive(Clone, Debug, Default)]
pub struct AnimationSummary {
    pub frames: usize,
    pub(crate) bytes: u64,
    /// Means over the clip's states, headline species: polarization, milling, DoA.
    pub polarization: f64,
    pub milling: f64,
    pub(crate) doa: f64,
}

/// `--animate OUT.gif` and its own flags.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct AnimateArgs {
    /// Render an episode to an animated GIF, headless (no window, no GPU): species colours, heading
    /// lines, optional --trails, a caption with the step and the live DoS/DoA/polarization/milling.
    #[arg(long, help_heading = "Modes", value_name = "OUT.gif")]
    pub(crate) animate: Option<std::path::PathBuf>,
    /// --animate: width of the arena image in pixels [default: 480].
    #[arg(long, help_heading = "Recording and animation", value_name = "PX", value_parser = clap::value_parser!(u32).range(64..=2048))]
    pub(crate) size: Option<u32>,
    /// --animate, viewer: fixed steps per frame [default: 1].
    #[arg(long, help_heading = "Recording and animation", value_name = "N", value_parser = super::args::at_least_one)]
    pub(crate) steps_per_frame: Option<usize>,
    /// --animate, viewer: draw fading trajectory tails (in the viewer, from the start).
    #[arg(long, help_heading = "Recording and animation")]
    pub(crate) trails: bool,
}

impl super::args::Mode for AnimateArgs {
    const MODE: &'static str = "animate";
    const TAKES: &'static [&'static str] =
        &["run", "scene", "seed", "steps", "prey", "predators", "count", "policy", "overwrite", "quiet", "snapshot"];
}

/// `--animate OUT.gif`: the deployed scene ([`super::deploy`]) drawn.
pub(crate) fn main(
    out: &Path,
    args: &AnimateArgs,
    deploy: &super::deploy::DeployArgs,
    shared: &super::args::Shared,
) -> crate::error::Result<()> {
    if out.extension().is_none_or(|e| e != "gif") {
        return Err(format!("--animate {}: the file must end in .gif", out.display()).into());
    }
    let existing = shared.common.existing();
    crate::io::check_target(out, existing).map_err(|e| format!("--animate {}: {e}", out.display()))?;
    let mut d = deploy.deploy(&shared.scene)?;
    let opts = AnimateOptions {
        steps: d.steps,
        steps_per_frame: args.steps_per_frame.unwrap_or(1),
        trails: args.trails,
        size: args.size.unwrap_or(480),
        title: deploy.title(&shared.scene),
        progress: !shared.common.quiet,
    };
    let s = animate(&mut d.sim, &opts, out, existing)?;
    crate::errln!(
        "coevo: wrote {} frames ({} steps, {:.1} MB) to {}{}; over the clip: polarization {:.3}, milling {:.3}, DoA {:.3}",
        s.frames,
        d.steps,
        s.bytes as f64 / 1e6,
        out.display(),
        d.actors,
        s.polarization,
        s.milling,
        s.doa
    )?;
    Ok(())
}

/// Steps `sim` for `opts.steps` steps and writes the GIF to `path` (atomically; see [`AtomicFile`]).
pub fn animate(
    sim: &mut Simulation,
    opts: &AnimateOptions,
    path: &Path,
    existing: Existing,
) -> crate::error::Result<AnimationSummary> {
    let io_err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    if opts.steps_per_frame == 0 || !(64..=2048).contains(&opts.size) {
        return Err(io_err(&"steps per frame must be ≥ 1 and the size within 64..=2048 pixels").into());
    }
    sim.world_mut().resource_mut::<Episode>().auto_reset = false;
    let registry = sim.world().resource::<SpeciesRegistry>().clone();
    let arena = *sim.world().resource::<Arena>();
    let prey = registry.headline();
    let colours: Vec<[u8; 3]> =
        registry.defs.iter().map(|d| d.colour.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)).collect();
    let palette = Palette::new(&colours);
    let (width, height) = (opts.size, opts.size + CAPTION);
    let mut file = AtomicFile::create(path, existing).map_err(|e| io_err(&e))?;
    let mut encoder =
        gif::Encoder::new(file.writer(), width as u16, height as u16, &palette.rgb).map_err(|e| io_err(&e))?;
    encoder.set_repeat(gif::Repeat::Infinite).map_err(|e| io_err(&e))?;
    let dt = sim.world().resource::<crate::sim::ActiveScene>().0.world.dt;
    let delay = ((dt * opts.steps_per_frame as f64 * 100.0).round() as u16).max(2);
    let svg_options = crate::svg::options();
    let frames = opts.steps / opts.steps_per_frame + 1;
    let bar = if opts.progress { ProgressBar::new(frames as u64) } else { ProgressBar::hidden() };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {eta} left").expect("a valid template"));
    let mut trails: HashMap<AgentId, VecDeque<DVec2>> = HashMap::new();
    let mut previous: Option<Vec<u8>> = None;
    let mut summary = AnimationSummary::default();
    let mut measured = 0usize;
    for step in 0..=opts.steps {
        if step > 0 {
            sim.step();
            sim.check()?;
        }
        if opts.trails {
            let world = sim.world_mut();
            for (id, x) in world.query::<(&AgentId, &Position)>().iter(world) {
                let t = trails.entry(*id).or_default();
                t.push_back(x.0);
                if t.len() > TRAIL_STEPS {
                    t.pop_front();
                }
            }
        }
        if let Some(s) = sim.world().resource::<SwarmMetrics>().now.get(prey).copied().flatten() {
            summary.polarization += s.polarization;
            summary.milling += s.milling;
            summary.doa += s.doa;
            measured += 1;
        }
        if step % opts.steps_per_frame != 0 {
            continue;
        }
        let svg = frame_svg(sim.world_mut(), &arena, &colours, &trails, opts, step, prey);
        let pixels = crate::svg::rasterize(&svg, &svg_options)?;
        let indices = palette.index(pixels.data());
        // Unchanged pixels are transparent: the previous frame shows through (disposal Keep).
        let buffer: Vec<u8> = match &previous {
            Some(prev) => {
                indices.iter().zip(prev).map(|(&i, &p)| if i == p { palette.transparent } else { i }).collect()
            }
            None => indices.clone(),
        };
        let frame = gif::Frame {
            width: width as u16,
            height: height as u16,
            delay,
            transparent: previous.as_ref().map(|_| palette.transparent),
            buffer: std::borrow::Cow::Owned(buffer),
            ..Default::default()
        };
        encoder.write_frame(&frame).map_err(|e| io_err(&e))?;
        previous = Some(indices);
        summary.frames += 1;
        bar.inc(1);
    }
    bar.finish_and_clear();
    encoder.into_inner().map_err(|e| io_err(&e))?;
    file.commit().map_err(|e| io_err(&e))?;
    summary.bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let n = measured.max(1) as f64;
    (summary.polarization, summary.milling, summary.doa) =
        (summary.polarization / n, summary.milling / n, summary.doa / n);
    Ok(summary)
}

/// The current state of a world drawn as an animation frame (`size` pixels square plus the caption),
/// as RGBA bytes, row by row: what the Python package's `render()` returns.
pub(crate) fn render_rgba(
    world: &mut bevy::prelude::World,
    size: u32,
    title: &str,
) -> crate::error::Result<(u32, u32, Vec<u8>)> {
    if !(64..=2048).contains(&size) {
        return Err(format!("render: the size must be within 64..=2048 pixels (got {size})").into());
    }
    let registry = world.resource::<SpeciesRegistry>().clone();
    let arena = *world.resource::<Arena>();
    let colours: Vec<[u8; 3]> =
        registry.defs.iter().map(|d| d.colour.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)).collect();
    let opts =
        AnimateOptions { steps: 0, steps_per_frame: 1, trails: false, size, title: title.into(), progress: false };
    let step = world.resource::<Episode>().step;
    let svg = frame_svg(world, &arena, &colours, &HashMap::new(), &opts, step, registry.headline());
    let pixels = crate::svg::rasterize(&svg, &crate::svg::options())?;
    Ok((pixels.width(), pixels.height(), pixels.data().to_vec()))
}

fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// One frame: the arena (clipped to itself), then the caption strip below it.
fn frame_svg(
    world: &mut bevy::prelude::World,
    arena: &Arena,
    colours: &[[u8; 3]],
    trails: &HashMap<AgentId, VecDeque<DVec2>>,
    opts: &AnimateOptions,
    step: usize,
    prey: usize,
) -> String {
    let size = opts.size as f64;
    // Walls get a margin so bodies touching them show whole; the torus fills the square.
    let margin = if arena.boundary == Boundary::Walls { 0.04 * arena.edge } else { 0.0 };
    let span = arena.edge + 2.0 * margin;
    let scale = size / span;
    let px = |p: DVec2| ((p.x + arena.half() + margin) * scale, (arena.half() + margin - p.y) * scale);
    let mut svg = String::new();
    let (w, h) = (opts.size, opts.size + CAPTION);
    let _ = write!(svg, r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}">"#);
    let _ = write!(svg, r#"<rect width="{w}" height="{h}" fill="{}"/>"#, hex(OUTSIDE));
    // A nested viewport clips everything drawn outside the arena image.
    let _ = write!(
        svg,
        r#"<svg x="0" y="0" width="{w}" height="{w}" overflow="hidden" shape-rendering="crispEdges"><rect width="{w}" height="{w}" fill="{}"/>"#,
        hex(FLOOR)
    );
    if arena.boundary == Boundary::Walls {
        let (x0, y0) = px(DVec2::new(-arena.half(), arena.half()));
        let e = arena.edge * scale;
        let _ = write!(
            svg,
            r#"<rect x="{x0:.1}" y="{y0:.1}" width="{e:.1}" height="{e:.1}" fill="none" stroke="{}" stroke-width="2"/>"#,
            hex(WALL)
        );
    }
    // Images of a point that may show: itself and, on the torus, its copies one edge away.
    let images = |p: DVec2, reach: f64| -> Vec<DVec2> {
        let mut out = vec![p];
        if arena.boundary == Boundary::Periodic {
            for dx in [-1.0, 0.0, 1.0] {
                for dy in [-1.0, 0.0, 1.0] {
                    let q = p + DVec2::new(dx, dy) * arena.edge;
                    if (dx != 0.0 || dy != 0.0) && q.x.abs() < arena.half() + reach && q.y.abs() < arena.half() + reach
                    {
                        out.push(q);
                    }
                }
            }
        }
        out
    };
    let mut agents: Vec<(AgentId, usize, DVec2, f64, f64, u32)> = world
        .query::<(&AgentId, &SpeciesId, &Position, &Heading, &Body, &Contacts)>()
        .iter(world)
        .map(|(id, s, x, h, b, c)| (*id, s.0, x.0, h.0, b.radius, c.now.caught + c.now.catching))
        .collect();
    agents.sort_by_key(|a| a.0);
    if opts.trails {
        for (id, s, _, _, radius, _) in &agents {
            let Some(trail) = trails.get(id) else { continue };
            let width = (0.6 * radius * scale).clamp(0.8, 3.0);
            for (k, (a, b)) in trail.iter().zip(trail.iter().skip(1)).enumerate() {
                // Each segment is a minimum-image step; one that crosses the seam is drawn from both ends
                // (each half clipped by the arena), so the seam shows no streak.
                let d = arena.delta(*a, *b);
                // Fading by age in four bands, not per step, so most trail pixels keep their colour from
                // one frame to the next (the GIF stores only changed pixels).
                let age = trail.len() - 1 - k;
                let opacity = 0.5 * (1.0 - (age * FADE_BANDS / TRAIL_STEPS) as f64 / FADE_BANDS as f64);
                let crosses = (*a + d - *b).length() > 1e-9;
                for (from, to) in [(*a, *a + d)].into_iter().chain(crosses.then_some((*b - d, *b))) {
                    let ((x1, y1), (x2, y2)) = (px(from), px(to));
                    let _ = write!(
                        svg,
                        r#"<line x1="{x1:.1}" y1="{y1:.1}" x2="{x2:.1}" y2="{y2:.1}" stroke="{}" stroke-opacity="{opacity:.2}" stroke-width="{width:.1}"/>"#,
                        hex(colours[*s])
                    );
                }
            }
        }
    }
    for (_, s, x, theta, radius, contacts) in &agents {
        let reach = radius * HEADING_LENGTH;
        for p in images(*x, reach) {
            let (cx, cy) = px(p);
            let r = (radius * scale).max(1.5);
            let (hx, hy) = px(p + DVec2::from_angle(*theta) * reach);
            let _ = write!(svg, r#"<circle cx="{cx:.1}" cy="{cy:.1}" r="{r:.1}" fill="{}"/>"#, hex(colours[*s]));
            let _ = write!(
                svg,
                r#"<line x1="{cx:.1}" y1="{cy:.1}" x2="{hx:.1}" y2="{hy:.1}" stroke="{}" stroke-width="{:.1}"/>"#,
                hex(colours[*s].map(|c| c / 2)),
                (0.35 * r).clamp(1.0, 3.0)
            );
            if *contacts > 0 {
                let _ = write!(
                    svg,
                    r#"<circle cx="{cx:.1}" cy="{cy:.1}" r="{:.1}" fill="none" stroke="{}" stroke-width="1.5"/>"#,
                    r + 2.0,
                    hex(CATCH)
                );
            }
        }
    }
    svg.push_str("</svg>");
    for (line, text) in caption(world, opts, prey, step).iter().enumerate() {
        let y = opts.size as f64 + 15.0 + 16.0 * line as f64;
        let text = text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
        let _ = write!(svg, r#"<text x="6" y="{y:.0}" font-size="12" fill="{}">{text}</text>"#, hex(TEXT));
    }
    svg.push_str("</svg>");
    svg
}

/// The two lines under a frame: the title and step, then the headline species' order and the contacts.
fn caption(world: &bevy::prelude::World, opts: &AnimateOptions, prey: usize, step: usize) -> [String; 2] {
    let m = world.resource::<SwarmMetrics>();
    let order = match m.now.get(prey).copied().flatten() {
        Some(s) => format!(
            "DoS {:.3}  DoA {:.2}  polarization {:.2}  milling {:.2}  clusters {}",
            s.dos, s.doa, s.polarization, s.milling, s.clusters
        ),
        None => String::new(),
    };
    let name = &world.resource::<SpeciesRegistry>().defs[prey].name;
    [
        format!("{}  ·  step {step}/{}", opts.title, opts.steps),
        format!("{name}: {order}  ·  in contact {}", m.catches_now),
    ]
}

/// One global palette: the scene's colours, each blended over the floor at eight levels (anti-aliased
/// edges, faded trails), the caption's text over its background, and a transparent entry for pixels that
/// did not change. Every pixel maps to its nearest entry (memoized: a frame has few distinct colours).
struct Palette {
    rgb: Vec<u8>,
    entries: Vec<[u8; 3]>,
    /// The index after the colours; the palette is padded to a power of two above it (a smaller palette
    /// means shorter LZW codes).
    transparent: u8,
}

impl Palette {
    const MAX_COLOURS: usize = 255;

    fn new(species: &[[u8; 3]]) -> Palette {
        let mut entries = vec![FLOOR, OUTSIDE];
        let blend = |a: [u8; 3], b: [u8; 3], t: f64| -> [u8; 3] {
            std::array::from_fn(|i| (a[i] as f64 + (b[i] as f64 - a[i] as f64) * t).round() as u8)
        };
        let mut inks: Vec<([u8; 3], [u8; 3])> = vec![(FLOOR, WALL), (FLOOR, CATCH), (OUTSIDE, TEXT)];
        for &c in species {
            inks.push((FLOOR, c));
            inks.push((FLOOR, c.map(|v| v / 2)));
            inks.push((c, c.map(|v| v / 2)));
        }
        for (under, ink) in inks {
            for level in 1..=8 {
                let e = blend(under, ink, level as f64 / 8.0);
                if !entries.contains(&e) && entries.len() < Self::MAX_COLOURS {
                    entries.push(e);
                }
            }
        }
        let transparent = entries.len() as u8;
        let mut rgb: Vec<u8> = entries.iter().flatten().copied().collect();
        rgb.resize((entries.len() + 1).next_power_of_two().max(4) * 3, 0);
        Palette { rgb, entries, transparent }
    }

    /// Palette indices of premultiplied RGBA pixels (opaque here: every frame paints its background).
    fn index(&self, rgba: &[u8]) -> Vec<u8> {
        let mut memo: HashMap<[u8; 3], u8> = HashMap::new();
        rgba.chunks_exact(4)
            .map(|p| {
                let c = [p[0], p[1], p[2]];
                *memo.entry(c).or_insert_with(|| {
                    let d = |e: &[u8; 3]| (0..3).map(|i| (e[i] as i32 - c[i] as i32).pow(2)).sum::<i32>();
                    (0..self.entries.len()).min_by_key(|&i| d(&self.entries[i])).expect("a palette") as u8
                })
            })
            .collect()
    }
}
