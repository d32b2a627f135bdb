//! Opponents from the past (`experiments/league.ron`; not in the paper). Algorithm 1 trains each species against the
//! other's *current* actor only, so nothing keeps an old skill alive: predators that stop meeting naive
//! prey can forget how to catch them (`coevo --crossplay` shows it). A species whose
//! `learning.opponents` is a `Pool` plays, with probability p per episode, against snapshots of every
//! other learning species kept earlier in the run: fictitious self-play (Heinrich, Lanctot & Silver
//! 2015), or prioritised by how badly the species does against each snapshot, as AlphaStar's league does
//! (Vinyals et al. 2019). The snapshots act without noise; in that episode only the training species
//! stores transitions, updates and lowers its exploration (σ and ε fall per episode a species trains).
//!
//! The pool is the actors `RUN/snapshots/` holds (before training and every `snapshot_every` episodes),
//! kept in memory as they are taken; a resumed run reads them back from those files, which hold the same
//! bytes, and the draws and the record of returns are in the checkpoint, so a resume continues the run
//! exactly. The draws come from their own stream (stream 2 of the seed): a scene without a pool draws
//! nothing and trains as before, to the byte.

use super::learner::SpeciesLearner;
use super::nets::Mlp;
use crate::scene::{Opponents, Pick, Policy, Scene};
use crate::sim::episode::SimRng;
use rand::distributions::{Distribution, WeightedIndex};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The stream of the seed the league draws from (0 is the environment's, 1 the networks'
/// initialisation, 16 + s species s's).
const LEAGUE_STREAM: u64 = 2;

/// The league of a training run with at least one pool.
#[derive(Clone, Debug)]
pub(crate) struct League {
    /// Species names, registry order.
    names: Vec<String>,
    /// Per species: its pool's probability and rule, None for the latest opponents.
    pools: Vec<Option<(f64, Pick)>>,
    /// Per species: its actor after each kept episode, oldest first; empty for species no pool draws from.
    history: Vec<Vec<(usize, Mlp)>>,
    /// Snapshots are kept every this many episodes (`learning.snapshot_every`).
    every: usize,
    /// The episode being played once its match is drawn, and the match (None: everyone plays itself).
    current: Option<(usize, Option<Match>)>,
    /// The match of the last episode that ended, for its row of `metrics.csv`.
    last: Option<Match>,
    /// The trainee's summed rewards in the current episode.
    episode_return: f64,
    pub(crate) state: LeagueState,
}

/// Who plays a pool episode: `trainee` trains against the snapshots `stand_in` names.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Match {
    pub(crate) trainee: usize,
    /// Per species: the episode of its snapshot that acts for it (None: it plays itself).
    pub(crate) stand_in: Vec<Option<usize>>,
}

/// What a checkpoint keeps of the league: the draws' stream and the record of returns.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct LeagueState {
    pub(crate) rng: ChaCha8Rng,
    /// Per trainee, opponent and snapshot played: the episodes and the trainee's summed return.
    pub(crate) record: Vec<Outcome>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct Outcome {
    pub(crate) trainee: String,
    pub(crate) opponent: String,
    /// The opponent's snapshot: its actor after this many episodes.
    pub(crate) snapshot: usize,
    pub(crate) episodes: u64,
    /// The trainee's rewards summed over its individuals, the episodes' steps and the episodes.
    pub(crate) return_sum: f64,
}

impl League {
    /// The league of a scene, None when no species trains against a pool. `species` are the fresh
    /// learners: their actors are the snapshots of episode 0.
    pub(crate) fn new(scene: &Scene, species: &[Option<SpeciesLearner>]) -> Option<League> {
        let pools: Vec<Option<(f64, Pick)>> = scene
            .species
            .iter()
            .map(|d| {
                scene.learning.opponents.iter().find(|(n, _)| n == &d.name).and_then(|(_, o)| match *o {
                    Opponents::Pool { p, pick } if d.policy == Policy::Learned => Some((p, pick)),
                    _ => None,
                })
            })
            .collect();
        if pools.iter().all(Option::is_none) {
            return None;
        }
        let history = (0..species.len())
            .map(|o| match &species[o] {
                Some(l) if drawn_from(&pools, species, o) => vec![(0, l.ddpg.actor.clone())],
                _ => vec![],
            })
            .collect();
        Some(League {
            names: scene.species.iter().map(|d| d.name.clone()).collect(),
            pools,
            history,
            every: scene.learning.snapshot_every.max(1),
            current: None,
            last: None,
            episode_return: 0.0,
            state: LeagueState { rng: SimRng::stream(scene.seed, LEAGUE_STREAM), record: vec![] },
        })
    }

    /// The league as a checkpoint after `episodes` episodes left it: `state` from the checkpoint, the
    /// pool read back from the run's snapshots of those episodes by `load` (species, episode, an actor of
    /// its shape: `snapshots::load_snapshot`, which checks them against the checkpoint's manifest).
    pub(crate) fn restore(
        &mut self,
        run: &Path,
        species: &[Option<SpeciesLearner>],
        episodes: usize,
        state: Option<LeagueState>,
        load: impl Fn(&str, usize, &Mlp) -> crate::error::Result<Mlp>,
    ) -> crate::error::Result<()> {
        let state = state.ok_or_else(|| {
            format!(
                "{}: the checkpoint holds no league although the scene trains against a pool (learning.opponents)",
                run.display()
            )
        })?;
        let mut history = vec![vec![]; self.history.len()];
        for (o, kept) in history.iter_mut().enumerate() {
            let Some(l) = species[o].as_ref().filter(|_| drawn_from(&self.pools, species, o)) else { continue };
            for episode in (0..=episodes).step_by(self.every) {
                kept.push((episode, load(&self.names[o], episode, &l.ddpg.actor)?));
            }
        }
        (self.history, self.state, self.current, self.last) = (history, state, None, None);
        Ok(())
    }

    /// The match of episode `index` (None: every species plays itself), drawn at its first step: the
    /// species with a pool draw in registry order, and the first whose draw falls under its p trains
    /// against the past this episode.
    pub(crate) fn play(&mut self, index: usize) -> Option<&Match> {
        if self.current.as_ref().is_none_or(|(i, _)| *i != index) {
            self.episode_return = 0.0;
            let drawn = self.draw_match();
            self.current = Some((index, drawn));
        }
        self.current.as_ref().and_then(|(_, m)| m.as_ref())
    }

    /// The actor standing in for species `s` in the current episode, if a snapshot plays it.
    pub(crate) fn stand_in(&self, s: usize) -> Option<&Mlp> {
        let m = self.current.as_ref()?.1.as_ref()?;
        let episode = m.stand_in.get(s).copied().flatten()?;
        self.history[s].iter().find(|(e, _)| *e == episode).map(|(_, actor)| actor)
    }

    /// Adds a step's rewards of the current episode's trainee to its return.
    pub(crate) fn add_rewards(&mut self, s: usize, rewards: &[f32]) {
        if self.current.as_ref().and_then(|(_, m)| m.as_ref()).is_some_and(|m| m.trainee == s) {
            self.episode_return += rewards.iter().map(|&r| r as f64).sum::<f64>();
        }
    }

    /// Closes episode `index`: records the trainee's return against each snapshot it met, and keeps every
    /// drawn-from species' actor when the run keeps a snapshot (`species` after the episode's updates).
    pub(crate) fn end_episode(&mut self, index: usize, species: &[Option<SpeciesLearner>]) {
        let played = self.current.take().filter(|(i, _)| *i == index).and_then(|(_, m)| m);
        if let Some(m) = &played {
            for (o, snapshot) in m.stand_in.iter().enumerate() {
                let Some(snapshot) = *snapshot else { continue };
                let (trainee, opponent) = (&self.names[m.trainee], &self.names[o]);
                let record = &mut self.state.record;
                let at = match record
                    .iter()
                    .position(|r| &r.trainee == trainee && &r.opponent == opponent && r.snapshot == snapshot)
                {
                    Some(at) => at,
                    None => {
                        record.push(Outcome {
                            trainee: trainee.clone(),
                            opponent: opponent.clone(),
                            snapshot,
                            episodes: 0,
                            return_sum: 0.0,
                        });
                        record.len() - 1
                    }
                };
                record[at].episodes += 1;
                record[at].return_sum += self.episode_return;
            }
        }
        self.last = played;
        if (index + 1).is_multiple_of(self.every) {
            for (o, kept) in self.history.iter_mut().enumerate() {
                if let (false, Some(l)) = (kept.is_empty(), &species[o]) {
                    kept.push((index + 1, l.ddpg.actor.clone()));
                }
            }
        }
    }

    /// A species' snapshot for trainee `t`: uniformly, or by rank of t's mean return against it.
    fn pick_snapshot(&mut self, t: usize, o: usize, pick: Pick) -> usize {
        let kept: Vec<usize> = self.history[o].iter().map(|(e, _)| *e).collect();
        let at = match pick {
            Pick::Uniform => self.state.rng.gen_range(0..kept.len()),
            Pick::Prioritised => {
                let mean = |e: usize| {
                    self.state
                        .record
                        .iter()
                        .find(|r| r.trainee == self.names[t] && r.opponent == self.names[o] && r.snapshot == e)
                        .map(|r| r.return_sum / r.episodes as f64)
                };
                // Worst first: the snapshots not yet played, then by mean return ascending, ties by episode.
                let mut order: Vec<(usize, Option<f64>)> = kept.iter().map(|&e| (e, mean(e))).collect();
                order.sort_by(|a, b| match (a.1, b.1) {
                    (None, None) => a.0.cmp(&b.0),
                    (None, Some(_)) => std::cmp::Ordering::Less,
                    (Some(_), None) => std::cmp::Ordering::Greater,
                    (Some(x), Some(y)) => x.total_cmp(&y).then(a.0.cmp(&b.0)),
                });
                let n = order.len();
                let weights = WeightedIndex::new((0..n).map(|r| n - r)).expect("n ≥ 1 positive weights");
                let episode = order[weights.sample(&mut self.state.rng)].0;
                kept.iter().position(|&e| e == episode).expect("drawn from kept")
            }
        };
        kept[at]
    }

    fn draw_match(&mut self) -> Option<Match> {
        for t in 0..self.pools.len() {
            let Some((p, pick)) = self.pools[t] else { continue };
            if !self.state.rng.gen_bool(p) {
                continue;
            }
            let stand_in = (0..self.history.len())
                .map(|o| (o != t && !self.history[o].is_empty()).then(|| self.pick_snapshot(t, o, pick)))
                .collect();
            return Some(Match { trainee: t, stand_in });
        }
        None
    }

    /// The columns of `metrics.csv` a league adds, per drawn-from species: `stand_in_NAME`, the episode of
    /// the snapshot that played it (blank: it played itself).
    pub(crate) fn columns(&self) -> Vec<String> {
        self.drawn().map(|o| format!("stand_in_{}", self.names[o])).collect()
    }

    /// The last ended episode's cells of [`League::columns`].
    pub(crate) fn cells(&self) -> Vec<String> {
        self.drawn()
            .map(|o| {
                self.last
                    .as_ref()
                    .and_then(|m| m.stand_in.get(o).copied().flatten())
                    .map_or(String::new(), |e| e.to_string())
            })
            .collect()
    }

    fn drawn(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.history.len()).filter(|&o| !self.history[o].is_empty())
    }
}

/// Whether some pool draws from species `o`: it learns, and another species trains against a pool.
fn drawn_from(pools: &[Option<(f64, Pick)>], species: &[Option<SpeciesLearner>], o: usize) -> bool {
    species[o].as_ref().is_some_and(|l| !l.frozen) && pools.iter().enumerate().any(|(t, p)| t != o && p.is_some())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learning::{Learners, Mode};

    /// The `paper` scene with the prey against a pool, and predator snapshots after 0, 100 and 200 episodes.
    fn league(pick: Pick) -> League {
        let mut scene = Scene::preset("paper").unwrap();
        scene.learning.hidden = 4;
        scene.learning.opponents = vec![("prey".into(), Opponents::Pool { p: 1.0, pick })];
        let learners = Learners::new(&scene, Mode::Train);
        let mut league = learners.league.expect("a pool makes a league");
        let actor = league.history[0][0].1.clone();
        league.history[0].extend([(100, actor.clone()), (200, actor)]);
        assert!(league.history[1].is_empty(), "no pool draws from the prey");
        league
    }

    fn shares(league: &mut League, draws: usize) -> [f64; 3] {
        let mut counts = [0usize; 3];
        for episode in 0..draws {
            let m = league.play(episode).expect("p = 1: every episode").clone();
            assert_eq!((m.trainee, m.stand_in[1]), (1, None), "the prey train, against predators only");
            counts[m.stand_in[0].unwrap() / 100] += 1;
        }
        counts.map(|c| c as f64 / draws as f64)
    }

    #[test]
    fn a_uniform_pool_draws_every_snapshot_alike() {
        let s = shares(&mut league(Pick::Uniform), 30_000);
        assert!(s.iter().all(|x| (x - 1.0 / 3.0).abs() < 0.02), "{s:?}");
    }

    #[test]
    fn a_prioritised_pool_draws_the_opponents_the_trainee_does_worst_against_most() {
        let mut league = league(Pick::Prioritised);
        // The prey's mean return: −5 against the predators of episode 200, −1 against 0, −3 against 100.
        for (snapshot, mean) in [(0, -1.0), (100, -3.0), (200, -5.0)] {
            league.state.record.push(Outcome {
                trainee: "prey".into(),
                opponent: "predator".into(),
                snapshot,
                episodes: 2,
                return_sum: 2.0 * mean,
            });
        }
        // Ranks worst first, weights 3 : 2 : 1 for episodes 200, 100 and 0.
        let s = shares(&mut league, 30_000);
        for (got, want) in s.iter().zip([1.0 / 6.0, 2.0 / 6.0, 3.0 / 6.0]) {
            assert!((got - want).abs() < 0.02, "{s:?}");
        }
        // A snapshot never played ranks before every played one.
        league.state.record.retain(|r| r.snapshot != 0);
        let s = shares(&mut league, 30_000);
        assert!(s[0] > 0.45 && s[2] > s[1], "{s:?}");
    }

    #[test]
    fn an_episode_against_the_past_is_recorded_and_snapshots_are_kept_on_schedule() {
        let mut scene = Scene::preset("paper").unwrap();
        scene.learning.hidden = 4;
        scene.learning.snapshot_every = 2;
        scene.learning.opponents = vec![("prey".into(), Opponents::Pool { p: 1.0, pick: Pick::Uniform })];
        let learners = Learners::new(&scene, Mode::Train);
        let mut league = learners.league.clone().unwrap();
        for episode in 0..4 {
            league.play(episode);
            league.add_rewards(1, &[-1.0, -2.0]);
            league.add_rewards(0, &[10.0]);
            league.end_episode(episode, &learners.species);
        }
        let kept: Vec<usize> = league.history[0].iter().map(|(e, _)| *e).collect();
        assert_eq!(kept, [0, 2, 4]);
        let played: u64 = league.state.record.iter().map(|r| r.episodes).sum();
        let total: f64 = league.state.record.iter().map(|r| r.return_sum).sum();
        assert_eq!((played, total), (4, -12.0), "only the trainee's rewards count");
        assert_eq!(league.cells().len(), 1);
    }
}
