//! Validation of a resolved scene: every value the physics or learning would choke on, the integrator's
//! stability bounds, and the memory a scene would need (before anything is allocated).

use super::schema::*;
use crate::error::Error;

/// What one world's app holds whatever its agents (its schedules, systems, resources and tables): about
/// 360 kB measured on the default scene (`run::env`'s tests), about 420 kB in a build with the viewer
/// (whose Bevy has more component types; its reflection registry, ~640 kB there, is dropped from a world
/// stepped from outside, `run::env::strip`); bounded here from above.
const WORLD_BYTES: f64 = if cfg!(feature = "viewer") { 460_000.0 } else { 420_000.0 };
/// What a parked world holds whatever its agents (its scene, clock, random streams and metrics): ~8 kB
/// measured on the default scene, bounded here from above.
const PARKED_BYTES: f64 = 10_000.0;

/// `field` refused with `message` unless `ok`.
fn check(ok: bool, field: &str, message: impl FnOnce() -> String) -> crate::error::Result<()> {
    if ok {
        Ok(())
    } else {
        Err(Error::field(field.to_string(), message()))
    }
}

fn positive(v: f64, field: &str) -> crate::error::Result<()> {
    check(v.is_finite() && v > 0.0, field, || format!("must be a finite number > 0 (got {v})"))
}

/// A rule's numbers with their names, owned.
fn named(numbers: &[(&str, f64)]) -> Vec<(String, f64)> {
    numbers.iter().map(|&(n, v)| (n.to_string(), v)).collect()
}

fn non_negative(v: f64, field: &str) -> crate::error::Result<()> {
    check(v.is_finite() && v >= 0.0, field, || format!("must be a finite number ≥ 0 (got {v})"))
}

/// A species' rule-based policy: its numbers finite, its radii non-negative, and each rule's own shape
/// (nested zones, increasing bin edges with one gain per bin, Vicsek's η in [0, 2π]).
fn check_policy(s: &SpeciesDef) -> crate::error::Result<()> {
    let f = |name: &str| format!("species[{}].{name}", s.name);
    let rule: Vec<(String, f64)> = match &s.policy {
        Policy::Zonal(rule) => {
            let radii = [rule.repulsion_radius, rule.alignment_radius, rule.attraction_radius];
            check(radii.windows(2).all(|w| w[0] <= w[1]), &f("policy"), || {
                format!("Zonal: the zones are nested: repulsion_radius ≤ alignment_radius ≤ attraction_radius (got {radii:?})")
            })?;
            named(&rule.numbers())
        }
        Policy::Binned(rule) => {
            let (e, bins) = (&rule.edges, rule.bins());
            check(bins > 0 && e[0] >= 0.0 && e.windows(2).all(|w| w[0] < w[1]), &f("policy.edges"), || {
                format!("Binned: at least two edges, increasing from ≥ 0 (got {e:?})")
            })?;
            let lists = [
                ("turn.kin", rule.turn.kin.len(), bins),
                ("turn.alignment", rule.turn.alignment.len(), bins),
                ("turn.evasion", rule.turn.evasion.len(), bins),
                ("thrust.kin", rule.thrust.kin.len(), bins),
                ("thrust.alignment", rule.thrust.alignment.len(), 0),
                ("thrust.evasion", rule.thrust.evasion.len(), bins),
            ];
            for (name, got, want) in lists {
                check(got == want, &f(&format!("policy.{name}")), || {
                    format!("Binned: {want} gains, one per bin between the {} edges (got {got})", e.len())
                })?;
            }
            rule.numbers()
        }
        Policy::Pursuit(rule) => named(&rule.numbers()),
        Policy::Vicsek(rule) => {
            check((0.0..=std::f64::consts::TAU).contains(&rule.noise), &f("policy.noise"), || {
                format!("Vicsek: η in radians, in [0, 2π] (got {})", rule.noise)
            })?;
            named(&rule.numbers())
        }
        Policy::Couzin(rule) => {
            // Widths and σ as well as radii: a negative one would silently empty a zone or the noise.
            for (name, v) in rule.numbers() {
                non_negative(v, &f(&format!("policy.{name}")))?;
            }
            named(&rule.numbers())
        }
        _ => vec![],
    };
    for (name, v) in &rule {
        let field = f(&format!("policy.{name}"));
        match name.ends_with("radius") {
            true => non_negative(*v, &field)?,
            false => check(v.is_finite(), &field, || format!("must be a finite number (got {v})"))?,
        }
    }
    Ok(())
}

impl Scene {
    /// Checks every value the physics or learning would choke on; an error names the field.
    pub fn validate(&self) -> crate::error::Result<()> {
        use crate::error::ResultExt;
        self.check_values().kind(crate::error::Kind::Scene)
    }

    fn check_values(&self) -> crate::error::Result<()> {
        let w = &self.world;
        positive(self.cluster_link, "cluster_link")?;
        if let Some(r) = self.confusion_radius {
            positive(r, "confusion_radius")?;
        }
        positive(w.arena_edge, "world.arena_edge")?;
        positive(w.dt, "world.dt")?;
        non_negative(w.drag, "world.drag")?;
        non_negative(w.contact_stiffness, "world.contact_stiffness")?;
        non_negative(w.wall_stiffness, "world.wall_stiffness")?;
        non_negative(w.wall_damping, "world.wall_damping")?;
        let r = &self.rewards;
        for (v, f) in [
            (r.contact, "rewards.contact"),
            (r.thrust_cost, "rewards.thrust_cost"),
            (r.turn_cost, "rewards.turn_cost"),
            (r.wall_penalty, "rewards.wall_penalty"),
        ] {
            check(v.is_finite(), f, || format!("must be a finite number (got {v})"))?;
        }
        check(
            self.observation_layout == ObservationLayout::Paper || self.observation_frame == ObservationFrame::World,
            "observation_layout",
            || "Authors is the authors' code's world-frame observation; it needs observation_frame: World".into(),
        )?;
        check(self.episode_steps > 0, "episode_steps", || "must be ≥ 1".into())?;
        check(self.episodes > 0, "episodes", || "must be ≥ 1".into())?;
        check(!self.species.is_empty(), "species", || "a scene needs at least one species".into())?;
        check(self.species.iter().any(|s| s.count > 0), "species", || {
            "every species has count 0: there would be no agent to simulate".into()
        })?;
        for (i, s) in self.species.iter().enumerate() {
            self.check_species(i, s)?;
        }
        for (i, r) in self.contact_rewards.iter().enumerate() {
            let field = format!("contact_rewards[{i}]");
            let catcher = self.species.iter().find(|s| s.name == r.catcher);
            check(catcher.is_some(), &field, || format!("no species named {:?} in this scene", r.catcher))?;
            check(self.species.iter().any(|s| s.name == r.caught), &field, || {
                format!("no species named {:?} in this scene", r.caught)
            })?;
            check(catcher.is_some_and(|c| c.catches.contains(&r.caught)), &field, || {
                format!("{} does not catch {}", r.catcher, r.caught)
            })?;
            check(r.catcher_reward.is_finite() && r.caught_reward.is_finite(), &field, || {
                "rewards must be finite numbers".into()
            })?;
            check(
                !self.contact_rewards[..i].iter().any(|o| o.catcher == r.catcher && o.caught == r.caught),
                &field,
                || format!("the pair {} → {} appears twice", r.catcher, r.caught),
            )?;
        }
        self.check_learning()?;
        self.check_stability()?;
        self.check_memory(crate::io::memory_bytes())
    }

    /// One species `s` (entry `i` of the scene's list): its name, body, policy, perception and sight.
    fn check_species(&self, i: usize, s: &SpeciesDef) -> crate::error::Result<()> {
        let w = &self.world;
        let f = |name: &str| format!("species[{}].{name}", s.name);
        check(!s.name.is_empty(), &format!("species[{i}].name"), || "must not be empty".into())?;
        // The longest file named after a species (`NAME-replay-FROM-TO.safetensors`) stays far
        // below the 255 bytes file systems allow.
        check(s.name.len() <= 64, &format!("species[{}…].name", &s.name[..s.name.floor_char_boundary(16)]), || {
            format!("at most 64 characters (got {}); it names checkpoint files and CSV columns", s.name.chars().count())
        })?;
        // Names become CSV column names (dos_prey, catches_by_hawk) and file names (prey-actor.safetensors).
        check(
            s.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-'),
            &format!("species[{i}].name"),
            || format!("{:?}: use letters, digits, _ and - only (it names CSV columns and checkpoint files)", s.name),
        )?;
        check(self.species.iter().filter(|o| o.name == s.name).count() == 1, &f("name"), || {
            format!("species name {:?} appears twice", s.name)
        })?;
        positive(s.mass, &f("mass"))?;
        positive(s.radius, &f("radius"))?;
        check(2.0 * s.radius < w.arena_edge, &f("radius"), || {
            format!("body diameter {} m does not fit in the arena of edge {} m", 2.0 * s.radius, w.arena_edge)
        })?;
        positive(s.max_speed, &f("max_speed"))?;
        non_negative(s.max_thrust, &f("max_thrust"))?;
        non_negative(s.max_turn_rate, &f("max_turn_rate"))?;
        check_policy(s)?;
        match s.perception {
            Perception::Full => {}
            Perception::FractionOfD(x) => positive(x, &f("perception"))?,
            Perception::Radius(x) => positive(x, &f("perception"))?,
        }
        for c in &s.colour {
            check((0.0..=1.0).contains(c), &f("colour"), || format!("components must be in [0, 1] (got {c})"))?;
        }
        self.check_sight(s)?;
        Ok(())
    }

    /// Whom species `s` catches, is blind to, and sees how (per-species perception, topological limits,
    /// fields of view): each a species of this scene, named once.
    fn check_sight(&self, s: &SpeciesDef) -> crate::error::Result<()> {
        let f = |name: &str| format!("species[{}].{name}", s.name);
        for target in &s.catches {
            check(self.species.iter().any(|o| &o.name == target), &f("catches"), || {
                format!("no species named {target:?} in this scene")
            })?;
            check(target != &s.name, &f("catches"), || "a species cannot catch itself".into())?;
        }
        for target in &s.blind_to {
            check(self.species.iter().any(|o| &o.name == target), &f("blind_to"), || {
                format!("no species named {target:?} in this scene")
            })?;
        }
        // Entry `i` of a per-species list (`perception_of`, `topological_limit_of`) names a species of
        // this scene that no earlier entry names.
        let once = |field: &str, names: &[&String], i: usize| {
            let target = names[i];
            check(self.species.iter().any(|o| &o.name == target), &f(field), || {
                format!("no species named {target:?} in this scene")
            })?;
            check(!names[..i].contains(&target), &f(field), || format!("{target:?} is named twice"))
        };
        let names: Vec<&String> = s.perception_of.iter().map(|(t, _)| t).collect();
        for (i, (_, perception)) in s.perception_of.iter().enumerate() {
            once("perception_of", &names, i)?;
            match *perception {
                Perception::Full => {}
                Perception::FractionOfD(x) | Perception::Radius(x) => positive(x, &f("perception_of"))?,
            }
        }
        let names: Vec<&String> = s.topological_limit_of.iter().map(|(t, _)| t).collect();
        for i in 0..names.len() {
            once("topological_limit_of", &names, i)?;
        }
        // Degrees of a field of view: more than none, at most all around.
        let field_of_view = |degrees: f64, field: &str| {
            check(degrees > 0.0 && degrees <= super::schema::FULL_VIEW, &f(field), || {
                format!("degrees in (0, 360] (360: all around, the paper; got {degrees})")
            })
        };
        field_of_view(s.field_of_view, "field_of_view")?;
        let names: Vec<&String> = s.field_of_view_of.iter().map(|(t, _)| t).collect();
        for (i, (_, degrees)) in s.field_of_view_of.iter().enumerate() {
            once("field_of_view_of", &names, i)?;
            field_of_view(*degrees, "field_of_view_of")?;
        }
        Ok(())
    }

    /// Algorithm 1's numbers and the opponents each learning species trains against.
    fn check_learning(&self) -> crate::error::Result<()> {
        let l = &self.learning;
        positive(l.actor_lr, "learning.actor_lr")?;
        positive(l.critic_lr, "learning.critic_lr")?;
        check((0.0..=1.0).contains(&l.gamma), "learning.gamma", || format!("must be in [0, 1] (got {})", l.gamma))?;
        check(l.tau > 0.0 && l.tau <= 1.0, "learning.tau", || format!("must be in (0, 1] (got {})", l.tau))?;
        check(l.hidden > 0, "learning.hidden", || "must be ≥ 1".into())?;
        check(l.batch_size > 0, "learning.batch_size", || "must be ≥ 1".into())?;
        check(l.buffer_capacity >= l.batch_size, "learning.buffer_capacity", || {
            format!("must hold at least one batch ({} transitions)", l.batch_size)
        })?;
        check(
            l.batch_draw != BatchDraw::WithoutReplacement || l.warmup_transitions >= l.batch_size,
            "learning.warmup_transitions",
            || format!("must be ≥ batch_size ({}) to draw a batch without replacement (batch_draw)", l.batch_size),
        )?;
        for (v, f) in [
            (l.noise_std, "learning.noise_std"),
            (l.epsilon, "learning.epsilon"),
            (l.exploration_decay, "learning.exploration_decay"),
            (l.exploration_floor, "learning.exploration_floor"),
        ] {
            non_negative(v, f)?;
        }
        check(l.epsilon <= 1.0, "learning.epsilon", || format!("is a probability (got {})", l.epsilon))?;
        // The noise is added to actions in [−1, 1] and clamped back: beyond a few units it is all saturation.
        check(l.noise_std <= 10.0, "learning.noise_std", || {
            format!("must be ≤ 10 on actions in [−1, 1] (got {})", l.noise_std)
        })?;
        for (i, (name, opponents)) in l.opponents.iter().enumerate() {
            let field = format!("learning.opponents[{name}]");
            let species = self.species.iter().find(|s| &s.name == name);
            check(species.is_some(), &field, || format!("no species named {name:?} in this scene"))?;
            check(!l.opponents[..i].iter().any(|(n, _)| n == name), &field, || "named twice".into())?;
            let Opponents::Pool { p, .. } = *opponents else { continue };
            check(species.is_some_and(|s| s.policy == Policy::Learned), &field, || {
                "only a Learned species trains against a pool".into()
            })?;
            check((0.0..=1.0).contains(&p), &field, || format!("p is a probability (got {p})"))?;
            check(self.species.iter().any(|s| &s.name != name && s.policy == Policy::Learned), &field, || {
                "no other Learned species to draw past opponents from".into()
            })?;
            check(l.snapshot_every > 0, "learning.snapshot_every", || {
                format!("must be ≥ 1: the pool of {name} is the snapshots kept every snapshot_every episodes")
            })?;
        }
        Ok(())
    }

    /// Refuses parameters for which the semi-implicit Euler step of Appendix B is unstable or unphysical.
    /// With m the mass of a body and Δt the step:
    ///
    /// - drag: `(drag + wall damping)·Δt/m ≤ 1`, else one step reverses the velocity it damps;
    /// - contacts: `k·Δt²·(1/m_a + 1/m_b) < 4` for the two lightest bodies, the stability bound ωΔt < 2 of
    ///   the symplectic Euler step for a spring between them (the `paper` preset: 1);
    /// - walls: `k_wall·Δt²/m < 4` for the lightest body (a spring to a fixed wall);
    /// - travel: one step moves a body at most `max_speed·Δt` (×√2 when clipped per component), which must
    ///   stay under half the arena edge, as the torus wrap and minimum-image distances assume.
    fn check_stability(&self) -> crate::error::Result<()> {
        let w = &self.world;
        let walls = w.boundary == Boundary::Walls;
        let damping = w.drag + if walls { w.wall_damping } else { 0.0 };
        let mut masses: Vec<(f64, &str)> = self.species.iter().map(|s| (s.mass, s.name.as_str())).collect();
        masses.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (lightest, name) = masses[0];
        let field = |f: &str| format!("species[{name}].{f}");
        let ratio = damping * w.dt / lightest;
        if ratio > 1.0 {
            let what = if walls { "(drag + wall_damping)·dt/mass" } else { "drag·dt/mass" };
            return Err(Error::field(field("mass"), format!("{what} = {ratio} exceeds 1: a step would reverse velocities (lower world.drag or world.dt, or raise the mass)")));
        }
        // The two lightest bodies that can meet: the lightest twice if its species has two agents.
        let lightest_species = self.species.iter().filter(|s| s.mass == lightest).map(|s| s.count).sum::<usize>();
        let second = if lightest_species >= 2 || masses.len() < 2 { lightest } else { masses[1].0 };
        let spring = w.contact_stiffness * w.dt * w.dt * (1.0 / lightest + 1.0 / second);
        if spring >= 4.0 {
            return Err(Error::field(
                "world.contact_stiffness".into(),
                format!("k·dt²·(1/m_a + 1/m_b) = {spring} for the lightest bodies ({name}) is ≥ 4: contacts would blow up (lower k or dt, or raise masses)"),
            ));
        }
        let wall = w.wall_stiffness * w.dt * w.dt / lightest;
        if walls && wall >= 4.0 {
            return Err(Error::field(
                "world.wall_stiffness".into(),
                format!("k_wall·dt²/m = {wall} for {name} is ≥ 4: wall contacts would blow up (lower it or dt)"),
            ));
        }
        let per_component = if w.speed_clip == SpeedClip::PerComponent { std::f64::consts::SQRT_2 } else { 1.0 };
        for s in &self.species {
            let travel = s.max_speed * w.dt * per_component;
            if travel >= w.arena_edge / 2.0 {
                let message = format!(
                    "a body would move {travel} m in one step, not less than half the arena edge ({} m)",
                    w.arena_edge / 2.0
                );
                return Err(Error::field(format!("species[{}].max_speed", s.name), message));
            }
        }
        Ok(())
    }

    /// Refuses a scene whose populations, observations or networks would need more than `limit` bytes,
    /// before anything is allocated. The estimate counts what grows with the scene: per agent its
    /// components and observation rows, per learned species its networks (online, target, Adam moments and
    /// the copies kept for saving) and its replay buffer (at most what a full run can fill).
    /// Bodies within contact reach of one agent, on average over the arena: the density of all agents
    /// times the area within twice the largest radius. Contacts and the nearest-neighbour search scan
    /// about this many bodies per agent, so a step costs about agents × (1 + this).
    pub(crate) fn bodies_within_reach(&self) -> f64 {
        let n = self.agents() as f64;
        let r = self.species.iter().map(|s| s.radius).fold(0.0, f64::max);
        n * std::f64::consts::PI * (2.0 * r).powi(2) / self.world.arena_edge.powi(2)
    }

    /// About how many seconds one step of this scene takes on one core: 1.5e-7 s per agent and body
    /// within its reach ([`Scene::bodies_within_reach`]), measured with `coevo --record` of 10 000 and
    /// 30 000 prey in the default arena (0.06 and 0.5 s a step); an order of magnitude, not a promise.
    pub(crate) fn estimated_step_seconds(&self) -> f64 {
        1.5e-7 * self.agents() as f64 * (1.0 + self.bodies_within_reach())
    }

    /// Agents of every species.
    pub(crate) fn agents(&self) -> usize {
        self.species.iter().map(|s| s.count).sum()
    }

    /// The bytes one world of this scene holds, without networks or replay buffers (an environment
    /// stepped from outside, `run::env`, has neither): the app itself ([`WORLD_BYTES`]) and per agent its
    /// observations, the copy paired with the next step's, and an inference chunk's, with ~512 B of
    /// components and perception arrays. `run::env`'s tests hold it against what a world holds, measured.
    pub(crate) fn world_bytes(&self) -> f64 {
        WORLD_BYTES + (0..self.species.len()).map(|s| self.species_agent_bytes(s)).sum::<f64>()
    }

    /// The bytes one world of this scene holds parked between its steps, when many worlds share an app
    /// (`run::env::pool`): its resources ([`PARKED_BYTES`]) and per agent its components, observations and
    /// perception arrays (~600 B with 54 observation numbers: 15 kB a world of 3 + 10, measured). Held
    /// against what a parked world holds by `run::env`'s tests.
    pub(crate) fn parked_bytes(&self) -> f64 {
        let agent = |s: usize| self.species[s].count as f64 * (self.observation_dim(s) as f64 * 4.0 + 420.0);
        PARKED_BYTES + (0..self.species.len()).map(agent).sum::<f64>()
    }

    fn species_agent_bytes(&self, s: usize) -> f64 {
        self.species[s].count as f64 * (3.0 * self.observation_dim(s) as f64 * 4.0 + 512.0)
    }

    pub(crate) fn check_memory(&self, limit: f64) -> crate::error::Result<()> {
        let gb = crate::io::bytes_shown;
        let refuse = |field: String, what: String, bytes: f64| {
            Err(Error::field(field, format!("{what} would need {}, more than the {} of memory coevo may use here (the least of free memory, the cgroup limit and ulimit -v)", gb(bytes), gb(limit))))
        };
        let mut total = 0.0;
        for (s, def) in self.species.iter().enumerate() {
            let n = def.count as f64;
            let d = self.observation_dim(s) as f64;
            let agents = self.species_agent_bytes(s);
            if agents > limit {
                let what = format!("{} agents with observations of {d} numbers (count, topological_limit)", def.count);
                return refuse(format!("species[{}]", def.name), what, agents);
            }
            total += agents;
            if matches!(def.policy, Policy::Learned | Policy::Frozen(_)) {
                let (h, l) = (self.learning.hidden as f64, &self.learning);
                let params = (d + 1.0) * h
                    + 2.0 * (h + 1.0) * h
                    + (h + 1.0) * 2.0
                    + (d + 3.0) * h
                    + 2.0 * (h + 1.0) * h
                    + h
                    + 1.0;
                let activations = l.batch_size as f64 * (2.0 * d + 8.0 * h) * 4.0 * 8.0;
                let nets = params * 4.0 * 10.0 + activations;
                if nets > limit {
                    let (field, what) = if activations > params * 40.0 {
                        ("learning.batch_size", format!("mini-batches of {} observations of {d} numbers", l.batch_size))
                    } else {
                        ("learning.hidden", format!("networks of width {} on {d} inputs", l.hidden))
                    };
                    return refuse(field.into(), what, nets);
                }
                let transitions = (l.buffer_capacity as f64).min(n * self.episode_steps as f64 * self.episodes as f64);
                let buffer = transitions * (2.0 * d + 3.0) * 4.0;
                if buffer > limit {
                    let what =
                        format!("a replay buffer of {transitions:.0} transitions of {d} numbers for {}", def.name);
                    return refuse("learning.buffer_capacity".into(), what, buffer);
                }
                total += nets + buffer;
            }
        }
        if total > limit {
            return refuse("species".into(), "this scene's agents, networks and replay buffers".into(), total);
        }
        Ok(())
    }
}
