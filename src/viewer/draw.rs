//! Drawing the world as in the paper's figures: each agent a filled circle of its body radius with a
//! short line for its heading, in its species' colour; the arena to scale, fitted beside the panels.
//!
//! Agents are drawn on their own entities: a new agent gets a mesh and a transform, and the transform
//! follows its `Position` and `Heading`. In a periodic arena a body that crosses an edge is also drawn on the
//! opposite side (a "ghost"), and everything outside the arena is masked, so crossing the seam shows no
//! streak. Overlays are gizmos: trails, catches, the selected agent's perception radius and neighbours.

use super::schedule::ViewerSet;
use crate::scene::Boundary;
use crate::sim::components::{AgentId, Body, Contacts, Heading, Position, Slot, SpeciesId};
use crate::sim::perception::{neighbour_slot, Batches};
use crate::sim::space::Arena;
use crate::sim::species::SpeciesRegistry;
use crate::sim::ActiveScene;
use bevy::camera::ScalingMode;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::math::DVec2;
use bevy::prelude::*;
use bevy::render::renderer::RenderAdapterInfo;
use bevy::window::PrimaryWindow;
use bevy_egui::input::EguiWantsInput;
use std::collections::VecDeque;

/// Around the arena and behind the panels.
pub(crate) const OUTSIDE: Color = Color::srgb(0.13, 0.13, 0.15);
/// The arena floor (the paper's figures are on white).
pub(crate) const FLOOR: Color = Color::srgb(0.98, 0.98, 0.97);
const WALL: Color = Color::srgb(0.42, 0.42, 0.46);
const SEAM: Color = Color::srgba(0.5, 0.5, 0.55, 0.5);
const CATCH: Color = Color::srgb(0.85, 0.05, 0.1);
const SELECTED: Color = Color::srgb(0.05, 0.05, 0.05);
/// The heading line runs from the centre to this many body radii.
const HEADING_LENGTH: f32 = 1.7;
/// Margin around the arena, as a fraction of its edge (room for walls).
const MARGIN: f32 = 0.04;

/// What the overlays show.
#[derive(Resource, Clone, Debug)]
pub(crate) struct Overlays {
    pub(crate) trails: bool,
    /// Trail length in steps.
    pub(crate) trail_length: usize,
    pub(crate) catches: bool,
    pub(crate) perception: bool,
    /// The rule of the selected agent where it is now: how it would turn with one more agent of species
    /// `rule_of` at each place around it (its response field amid its current observation).
    pub(crate) rule: bool,
    pub(crate) rule_of: usize,
}

/// The gizmos of the rule overlay ([`draw_rule`]): thicker lines, so its hatched cells read as filled.
#[derive(Default, Reflect, GizmoConfigGroup)]
struct RuleGizmos;

/// The selected agent, by id so that it stays selected across respawns.
#[derive(Resource, Default, Clone, Copy, Debug)]
pub(crate) struct Selection(pub Option<AgentId>);

/// Room the egui panels take at the window's edges, in logical pixels (written by the panel).
#[derive(Resource, Default, Clone, Copy, Debug)]
pub(crate) struct PanelSpace {
    pub(crate) left: f32,
    pub(crate) right: f32,
}

/// Past positions of an agent, newest last.
#[derive(Component, Default)]
pub(crate) struct Trail(pub VecDeque<DVec2>);

/// A periodic image of a body near an edge; `heading` is its heading line's entity.
#[derive(Component)]
struct Ghost {
    heading: Entity,
}

/// The arena floor, mask and walls of the current scene.
#[derive(Component)]
struct ArenaPiece;

/// Meshes and materials per species, for the current scene.
#[derive(Resource, Default)]
struct Looks {
    circle: Handle<Mesh>,
    line: Handle<Mesh>,
    body: Vec<Handle<ColorMaterial>>,
    heading: Vec<Handle<ColorMaterial>>,
}

pub(crate) struct DrawPlugin {
    pub(crate) trails: bool,
    pub(crate) select: Option<u32>,
    pub(crate) rule_of: Option<usize>,
}

impl Plugin for DrawPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(Overlays {
            trails: self.trails,
            trail_length: 60,
            catches: true,
            perception: true,
            rule: self.rule_of.is_some(),
            rule_of: self.rule_of.unwrap_or(0),
        })
        .insert_resource(Selection(self.select.map(AgentId)))
        .init_resource::<PanelSpace>()
        .init_resource::<Looks>()
        .init_gizmo_group::<RuleGizmos>()
        .add_systems(
            Startup,
            (spawn_camera, |mut store: ResMut<GizmoConfigStore>| {
                store.config_mut::<RuleGizmos>().0.line.width = 3.0;
            }),
        )
        .add_systems(PostStartup, no_msaa_on_software_rendering)
        .add_systems(
            Update,
            (
                dress_scene.run_if(resource_changed::<ActiveScene>),
                dress_agents,
                place_agents,
                place_ghosts,
                fit_camera,
                select_on_click,
                draw_overlays,
                draw_rule,
            )
                .chain()
                .in_set(ViewerSet::Draw),
        );
    }
}

fn spawn_camera(mut commands: Commands) {
    // No tonemapping: the screen shows the species' colours exactly.
    commands.spawn((Camera2d, Tonemapping::None));
}

/// Multisampling costs a software rasterizer (llvmpipe under Xvfb) more than half its frame rate, so it
/// is turned off there; a GPU keeps Bevy's default 4×.
fn no_msaa_on_software_rendering(
    adapter: Option<Res<RenderAdapterInfo>>,
    mut camera: Single<&mut Msaa, With<Camera2d>>,
    mut checked: Local<bool>,
) {
    let Some(adapter) = adapter.filter(|_| !*checked) else { return };
    *checked = true;
    // wgpu's DeviceType::Cpu (the enum is not re-exported by Bevy).
    if format!("{:?}", adapter.device_type) == "Cpu" {
        **camera = Msaa::Off;
        info!("software rendering ({}): multisampling off", adapter.name);
    }
}

/// Floor, mask, walls and the species' looks for the current scene.
fn dress_scene(
    mut commands: Commands,
    scene: Res<ActiveScene>,
    old: Query<Entity, With<ArenaPiece>>,
    mut looks: ResMut<Looks>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<ColorMaterial>>,
) {
    for e in &old {
        commands.entity(e).despawn();
    }
    let edge = scene.0.world.arena_edge as f32;
    let mut piece = |size: Vec2, at: Vec2, z: f32, colour: Color| {
        commands.spawn((
            ArenaPiece,
            Mesh2d(meshes.add(Rectangle::from_size(size))),
            MeshMaterial2d(materials.add(colour)),
            Transform::from_translation(at.extend(z)),
        ));
    };
    piece(Vec2::splat(edge), Vec2::ZERO, 0.0, FLOOR);
    // The mask: four wide bands around the arena hide whatever reaches past an edge (on the torus, the
    // part of a body that has wrapped is drawn at the other edge). Walls are soft (Hooke): a body pressed
    // against one overlaps it by up to its radius, so there bodies are drawn over the walls and the mask.
    let walls = scene.0.world.boundary == Boundary::Walls;
    let (mask_z, wall_z) = if walls { (0.2, 0.3) } else { (10.0, 11.0) };
    let far = 50.0 * edge;
    for dir in [Vec2::X, Vec2::NEG_X, Vec2::Y, Vec2::NEG_Y] {
        let size = if dir.x != 0.0 { Vec2::new(far, 3.0 * far) } else { Vec2::new(3.0 * far, far) };
        piece(size, dir * (edge + far) / 2.0, mask_z, OUTSIDE);
    }
    if walls {
        let t = 0.6 * MARGIN * edge;
        for dir in [Vec2::X, Vec2::NEG_X, Vec2::Y, Vec2::NEG_Y] {
            let size = if dir.x != 0.0 { Vec2::new(t, edge + 2.0 * t) } else { Vec2::new(edge + 2.0 * t, t) };
            piece(size, dir * (edge + t) / 2.0, wall_z, WALL);
        }
    }
    looks.circle = meshes.add(Circle::new(1.0));
    // From the centre forward, in body radii (the parent's scale).
    looks.line = meshes.add(Rectangle::new(HEADING_LENGTH, 0.22));
    looks.body = scene.0.species.iter().map(|s| materials.add(species_colour(s.colour))).collect();
    looks.heading = scene.0.species.iter().map(|s| materials.add(shade(s.colour, 0.6))).collect();
}

/// A species' colour as its scene gives it (sRGB).
pub(crate) fn species_colour(c: [f32; 3]) -> Color {
    Color::srgb(c[0], c[1], c[2])
}

/// A species' colour mixed toward black by `f` (its heading lines, its neighbour lines).
fn shade(c: [f32; 3], f: f32) -> Color {
    species_colour(c.map(|x| x * (1.0 - f)))
}

/// A body: the circle with the heading line as a child.
fn spawn_body(commands: &mut EntityCommands, looks: &Looks, species: usize) -> Entity {
    let mut heading = Entity::PLACEHOLDER;
    commands.insert((Mesh2d(looks.circle.clone()), MeshMaterial2d(looks.body[species].clone()))).with_children(|c| {
        heading = c
            .spawn((
                Mesh2d(looks.line.clone()),
                MeshMaterial2d(looks.heading[species].clone()),
                Transform::from_xyz(HEADING_LENGTH / 2.0, 0.0, 0.5),
            ))
            .id();
    });
    heading
}

fn dress_agents(mut commands: Commands, looks: Res<Looks>, new: Query<(Entity, &SpeciesId), Added<AgentId>>) {
    for (e, s) in &new {
        if s.0 < looks.body.len() {
            spawn_body(&mut commands.entity(e), &looks, s.0);
            commands.entity(e).insert(Trail::default());
        }
    }
}

/// Depth of a species' bodies: later species above earlier ones, all below the torus's mask (above the
/// walls and their mask).
fn body_z(species: usize) -> f32 {
    1.0 + 0.1 * species as f32
}

fn body_transform(x: DVec2, theta: f64, radius: f64, species: usize) -> Transform {
    Transform::from_translation(x.as_vec2().extend(body_z(species)))
        .with_rotation(Quat::from_rotation_z(theta as f32))
        .with_scale(Vec3::splat(radius as f32))
}

fn place_agents(mut agents: Query<(&Position, &Heading, &Body, &SpeciesId, &mut Transform), With<AgentId>>) {
    for (x, h, body, s, mut t) in &mut agents {
        *t = body_transform(x.0, h.0, body.radius, s.0);
    }
}

/// The offsets at which a body near an edge of a periodic arena reappears.
fn periodic_images(arena: &Arena, x: DVec2, reach: f64) -> impl Iterator<Item = DVec2> + '_ {
    let (edge, half) = (arena.edge, arena.half());
    let periodic = arena.boundary == Boundary::Periodic;
    (-1..=1).flat_map(move |i| (-1..=1).map(move |j| DVec2::new(i as f64 * edge, j as f64 * edge))).filter(move |o| {
        let p = x + *o;
        periodic && *o != DVec2::ZERO && p.x.abs() < half + reach && p.y.abs() < half + reach
    })
}

fn place_ghosts(
    mut commands: Commands,
    looks: Res<Looks>,
    arena: Res<Arena>,
    agents: Query<(&Position, &Heading, &Body, &SpeciesId), With<AgentId>>,
    mut ghosts: Query<
        (Entity, &Ghost, &mut Transform, &mut Visibility, &mut MeshMaterial2d<ColorMaterial>),
        Without<AgentId>,
    >,
    mut lines: Query<&mut MeshMaterial2d<ColorMaterial>, (Without<Ghost>, Without<AgentId>)>,
) {
    let mut pool = ghosts.iter_mut();
    for (x, h, body, s) in &agents {
        let reach = body.radius * HEADING_LENGTH as f64;
        for offset in periodic_images(&arena, x.0, reach) {
            let t = body_transform(x.0 + offset, h.0, body.radius, s.0);
            match pool.next() {
                Some((_, ghost, mut transform, mut visible, mut material)) => {
                    *transform = t;
                    *visible = Visibility::Inherited;
                    material.0 = looks.body[s.0].clone();
                    if let Ok(mut line) = lines.get_mut(ghost.heading) {
                        line.0 = looks.heading[s.0].clone();
                    }
                }
                None => {
                    // The pool grows; the new ghost shows from the next frame.
                    let mut e = commands.spawn((t, Visibility::Inherited));
                    let heading = spawn_body(&mut e, &looks, s.0);
                    e.insert(Ghost { heading });
                }
            }
        }
    }
    for (_, _, _, mut visible, _) in pool {
        *visible = Visibility::Hidden;
    }
}

/// Fits the arena into the part of the window the panels leave free.
fn fit_camera(
    window: Single<&Window, With<PrimaryWindow>>,
    space: Res<PanelSpace>,
    arena: Res<Arena>,
    mut camera: Single<(&mut Transform, &mut Projection), With<Camera2d>>,
) {
    let (w, h) = (window.width(), window.height());
    let free = Vec2::new((w - space.left - space.right).max(50.0), h.max(50.0));
    let per_pixel = arena.edge as f32 * (1.0 + 2.0 * MARGIN) / free.min_element();
    let centre_px = Vec2::new(space.left + free.x / 2.0, free.y / 2.0);
    let (transform, projection) = &mut *camera;
    transform.translation.x = -(centre_px.x - w / 2.0) * per_pixel;
    transform.translation.y = (centre_px.y - h / 2.0) * per_pixel;
    if let Projection::Orthographic(o) = &mut **projection {
        o.scaling_mode = ScalingMode::WindowSize;
        o.scale = per_pixel;
    }
}

/// A click on the arena selects the agent under the pointer (or nearest within a few pixels); a click on
/// empty floor clears the selection.
fn select_on_click(
    buttons: Res<ButtonInput<MouseButton>>,
    egui: Res<EguiWantsInput>,
    window: Single<&Window, With<PrimaryWindow>>,
    camera: Single<(&Camera, &GlobalTransform, &Projection), With<Camera2d>>,
    arena: Res<Arena>,
    agents: Query<(&AgentId, &Position, &Body)>,
    mut selection: ResMut<Selection>,
) {
    if !buttons.just_pressed(MouseButton::Left) || egui.wants_any_pointer_input() {
        return;
    }
    let Some(cursor) = window.cursor_position() else { return };
    let (camera, at, projection) = *camera;
    let Ok(p) = camera.viewport_to_world_2d(at, cursor) else { return };
    let p = p.as_dvec2();
    if p.x.abs() > arena.half() || p.y.abs() > arena.half() {
        return;
    }
    let slack = match projection {
        Projection::Orthographic(o) => 6.0 * o.scale as f64,
        _ => 0.0,
    };
    selection.0 = agents
        .iter()
        .map(|(id, x, body)| (*id, arena.delta(p, x.0).length() - body.radius))
        .filter(|&(_, gap)| gap <= slack)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(id, _)| id);
}

/// Clips segment a–b to the square |x|, |y| ≤ half (Liang–Barsky).
fn clip(a: DVec2, b: DVec2, half: f64) -> Option<(DVec2, DVec2)> {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [(-d.x, a.x + half), (d.x, half - a.x), (-d.y, a.y + half), (d.y, half - a.y)] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then(|| (a + t0 * d, a + t1 * d))
}

/// Draws a–b (a in the arena, b = a + a minimum-image displacement) with every periodic image that falls
/// inside the arena, so a line across the seam leaves one side and enters the other.
fn wrapped_line(gizmos: &mut Gizmos, arena: &Arena, a: DVec2, b: DVec2, colours: (Color, Color)) {
    let half = arena.half();
    let inside = |p: DVec2| p.x.abs() <= half && p.y.abs() <= half;
    if inside(a) && inside(b) || arena.boundary == Boundary::Walls {
        gizmos.line_gradient_2d(a.as_vec2(), b.as_vec2(), colours.0, colours.1);
        return;
    }
    for i in -1..=1 {
        for j in -1..=1 {
            let o = DVec2::new(i as f64, j as f64) * arena.edge;
            if let Some((p, q)) = clip(a + o, b + o, half) {
                gizmos.line_gradient_2d(p.as_vec2(), q.as_vec2(), colours.0, colours.1);
            }
        }
    }
}

/// A circle as segments, wrapped like [`wrapped_line`].
fn wrapped_circle(gizmos: &mut Gizmos, arena: &Arena, centre: DVec2, radius: f64, colour: Color) {
    const SEGMENTS: usize = 96;
    let point = |k: usize| centre + radius * DVec2::from_angle(k as f64 * std::f64::consts::TAU / SEGMENTS as f64);
    for k in 0..SEGMENTS {
        wrapped_line(gizmos, arena, point(k), point(k + 1), (colour, colour));
    }
}

/// After each step: appends every agent's position to its trail (when trails are shown).
pub(crate) fn record_trails(world: &mut World) {
    let overlays = world.resource::<Overlays>().clone();
    if !overlays.trails {
        return;
    }
    for (x, mut trail) in world.query::<(&Position, &mut Trail)>().iter_mut(world) {
        trail.0.push_back(x.0);
        while trail.0.len() > overlays.trail_length {
            trail.0.pop_front();
        }
    }
}

type OverlayAgents<'w, 's> = Query<
    'w,
    's,
    (
        &'static AgentId,
        &'static Position,
        &'static Heading,
        &'static Body,
        &'static SpeciesId,
        &'static Contacts,
        &'static Slot,
        Option<&'static Trail>,
    ),
>;

fn draw_overlays(
    mut gizmos: Gizmos,
    overlays: Res<Overlays>,
    selection: Res<Selection>,
    arena: Res<Arena>,
    registry: Res<SpeciesRegistry>,
    batches: Res<Batches>,
    scene: Res<crate::sim::ActiveScene>,
    agents: OverlayAgents,
) {
    let arena = *arena;
    if arena.boundary == Boundary::Periodic {
        gizmos.rect_2d(Isometry2d::IDENTITY, Vec2::splat(arena.edge as f32), SEAM);
    }
    let rgb = |s: usize| registry.defs.get(s).map_or([0.5; 3], |d| d.colour);
    for (id, x, heading, body, s, contacts, slot, trail) in &agents {
        if overlays.trails {
            if let Some(trail) = trail {
                let n = trail.0.len();
                let c = species_colour(rgb(s.0));
                for (k, (a, b)) in trail.0.iter().zip(trail.0.iter().skip(1)).enumerate() {
                    // Fading with age; the segment is a minimum-image step, so the seam shows no streak.
                    let alpha = |k: usize| 0.55 * k as f32 / n as f32;
                    wrapped_line(
                        &mut gizmos,
                        &arena,
                        *a,
                        *a + arena.delta(*a, *b),
                        (c.with_alpha(alpha(k)), c.with_alpha(alpha(k + 1))),
                    );
                }
            }
        }
        let caught = contacts.now.caught > 0 || contacts.now.catching > 0;
        if overlays.catches && caught {
            gizmos.circle_2d(x.0.as_vec2(), 1.6 * body.radius as f32, CATCH).resolution(24);
        }
        if selection.0 != Some(*id) {
            continue;
        }
        gizmos.circle_2d(x.0.as_vec2(), 1.35 * body.radius as f32, SELECTED).resolution(32);
        if !overlays.perception || s.0 >= registry.len() || s.0 >= batches.species.len() {
            continue;
        }
        let r = registry.perception_radius[s.0];
        if r < arena.edge * std::f64::consts::SQRT_2 / 2.0 {
            wrapped_circle(&mut gizmos, &arena, x.0, r, SELECTED.with_alpha(0.6));
        }
        // The blind sector behind (`field_of_view`), the widest over the observed species: its two edges
        // and its arc, out to the perception radius or a quarter of the arena, whichever is nearer.
        if let Some(cos_half) = registry.view[s.0].iter().flatten().copied().reduce(f64::max) {
            let (half, reach) = (cos_half.acos(), r.min(arena.edge / 4.0));
            let theta = heading.0;
            let ray = |a: f64| x.0 + reach * DVec2::from_angle(a);
            let colour = SELECTED.with_alpha(0.45);
            wrapped_line(&mut gizmos, &arena, x.0, ray(theta + half), (colour, colour));
            wrapped_line(&mut gizmos, &arena, x.0, ray(theta - half), (colour, colour));
            const SEGMENTS: usize = 24;
            let blind = std::f64::consts::TAU - 2.0 * half;
            let arc = |k: usize| ray(theta + half + blind * k as f64 / SEGMENTS as f64);
            for k in 0..SEGMENTS {
                wrapped_line(&mut gizmos, &arena, arc(k), arc(k + 1), (colour, colour));
            }
        }
        // Lines to the neighbours exactly as the observation holds them (Δx, Δy of each filled slot).
        let batch = &batches.species[s.0];
        if (slot.row as usize) < batch.n {
            let obs = batch.observation(slot.row as usize);
            for t in 0..registry.len() {
                for n in 0..registry.slots(s.0, t) {
                    if let Some([dx, dy, _, _]) = neighbour_slot(obs, &registry, s.0, t, n) {
                        // Body-frame displacements are (ahead, left) of the observer: turned back to the world.
                        let d = DVec2::new(dx as f64, dy as f64);
                        let d = match scene.0.observation_frame {
                            crate::scene::ObservationFrame::World => d,
                            crate::scene::ObservationFrame::Body => d.rotate(heading.unit()),
                        };
                        let to = x.0 + d;
                        let c = shade(rgb(t), 0.25);
                        wrapped_line(&mut gizmos, &arena, x.0, to, (c, c));
                    }
                }
            }
        }
    }
}

/// The field last drawn: the observation it was computed on, the probed species and the field.
type DrawnRule = Option<(Vec<f32>, usize, crate::analysis::response::Field)>;

/// The selected agent's response field amid its current observation ([`Overlays::rule`]): a cell per
/// place of the probe agent, red where the probe would turn the agent more to the left than it turns
/// now, blue more to the right, as strong as the difference. The field is computed again only when the
/// observation or the probed species changes.
#[allow(clippy::too_many_arguments)]
fn draw_rule(
    mut gizmos: Gizmos<RuleGizmos>,
    overlays: Res<Overlays>,
    selection: Res<Selection>,
    arena: Res<Arena>,
    batches: Res<Batches>,
    scene: Res<crate::sim::ActiveScene>,
    registry: Res<SpeciesRegistry>,
    learners: Res<crate::learning::Learners>,
    agents: Query<(&AgentId, &Position, &Heading, &SpeciesId, &Slot)>,
    mut drawn: Local<DrawnRule>,
) {
    use crate::analysis::response::{actions, field_here};
    if !overlays.rule {
        return;
    }
    let Some((_, x, heading, s, slot)) = agents.iter().find(|(id, ..)| selection.0 == Some(**id)) else { return };
    let Some(batch) = batches.species.get(s.0).filter(|b| (slot.row as usize) < b.n) else { return };
    let obs = batch.observation(slot.row as usize);
    let t = overlays.rule_of;
    if !drawn.as_ref().is_some_and(|(o, probed, _)| o == obs && *probed == t) {
        let dev = crate::learning::nets::Dev::default();
        let act = |k: usize, b: &[f32], rows: usize| actions(&learners, &registry, &scene.0, &dev, k, b, rows);
        *drawn = field_here(&scene.0, &act, s.0, t, obs).map(|f| (obs.to_vec(), t, f));
    }
    let Some((_, _, field)) = drawn.as_ref() else { return };
    let width = (field.centres[1] - field.centres[0]) as f32;
    // The field's frame in the world: the agent's body frame, or the world's own.
    let facing = match scene.0.observation_frame {
        crate::scene::ObservationFrame::World => DVec2::X,
        crate::scene::ObservationFrame::Body => heading.unit(),
    };
    let angle = facing.to_angle() as f32;
    // Each cell hatched with lines across it, so it reads as filled at any zoom the arena is drawn at.
    const HATCHES: usize = 4;
    let across = Vec2::from_angle(angle + std::f32::consts::FRAC_PI_2);
    let along = Vec2::from_angle(angle);
    for (row, &left) in field.centres.iter().enumerate() {
        for (column, &ahead) in field.centres.iter().enumerate() {
            let change = field.turn[row][column] - field.alone[1];
            if !change.is_finite() || change.abs() < 0.02 {
                continue;
            }
            let at = arena.wrap(x.0 + DVec2::new(ahead, left).rotate(facing)).as_vec2();
            let colour = if change > 0.0 { Color::srgb(0.8, 0.1, 0.1) } else { Color::srgb(0.1, 0.25, 0.85) };
            let colour = colour.with_alpha(0.85 * (2.0 * change.abs()).min(1.0) as f32);
            for k in 0..HATCHES {
                let offset = across * width * ((k as f32 + 0.5) / HATCHES as f32 - 0.5);
                let half = along * width * 0.5;
                gizmos.line_2d(at + offset - half, at + offset + half, colour);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_the_inside_part() {
        let (a, b) = clip(DVec2::new(0.5, 0.0), DVec2::new(1.5, 0.0), 1.0).unwrap();
        assert_eq!((a, b), (DVec2::new(0.5, 0.0), DVec2::new(1.0, 0.0)));
        assert!(clip(DVec2::new(1.5, 0.0), DVec2::new(2.0, 3.0), 1.0).is_none());
    }

    #[test]
    fn only_bodies_at_an_edge_of_a_periodic_arena_have_ghosts() {
        let torus = Arena { edge: 2.0, boundary: Boundary::Periodic };
        assert_eq!(periodic_images(&torus, DVec2::new(0.0, 0.0), 0.1).count(), 0);
        let east: Vec<_> = periodic_images(&torus, DVec2::new(0.95, 0.0), 0.1).collect();
        assert_eq!(east, vec![DVec2::new(-2.0, 0.0)]);
        assert_eq!(periodic_images(&torus, DVec2::new(0.95, -0.95), 0.1).count(), 3, "a corner shows in three others");
        let boxed = Arena { edge: 2.0, boundary: Boundary::Walls };
        assert_eq!(periodic_images(&boxed, DVec2::new(0.95, 0.0), 0.1).count(), 0);
    }
}
