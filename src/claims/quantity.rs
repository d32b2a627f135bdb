//! What each [`Quantity`] of a claim is: its value from a run's files ([`quantity`], through the one
//! definition of every derived quantity, [`derive`]), its summary.csv column ([`column`]), its words
//! ([`quantity_name`]) and the value it has by chance ([`chance_level`]). Each is an exhaustive match or
//! names every variant it leaves to another, so a new quantity is a compile error until every one says
//! what it is.

use super::curves::{extreme_word, reach90, window_mean, Shape, AUTHORS_CURVES, CURVES, HALFWAY_WINDOW, START};
use super::file::{Claim, Curve, Experiment, Fit, Order, Quantity};
use super::results::{RunData, SETTLED_STEPS};
use super::stats::mean;
use super::verdict::is_effect;

/// A run's value of a quantity, from its own files ([`RunData`]).
pub(crate) fn quantity(exp: &Experiment, d: &RunData, q: &Quantity) -> f64 {
    derive(&exp.spec.evaluations, q, &|p| primitive(d, p))
}

/// The value of a primitive quantity (one with a [`column`] of its own) from a run's files.
pub(crate) fn primitive(d: &RunData, q: &Quantity) -> f64 {
    let settled = |v: &[f64]| {
        mean(&v[v.len().saturating_sub(SETTLED_STEPS)..].iter().copied().filter(|x| x.is_finite()).collect::<Vec<_>>())
            .unwrap_or(f64::NAN)
    };
    let eval = |e: &str, o: Order| d.evals.get(e).map_or(f64::NAN, |x| settled(x.series(o.name())));
    match q {
        Quantity::DosFirst => window_mean(&d.dos, true),
        Quantity::DosLast => window_mean(&d.dos, false),
        Quantity::DoaFirst => window_mean(&d.doa, true),
        Quantity::DoaLast => window_mean(&d.doa, false),
        Quantity::CatchesFirst => window_mean(&d.catches, true),
        Quantity::CatchesLast => window_mean(&d.catches, false),
        Quantity::TrainingFirst(o) => d.orders.get(o.name()).map_or(f64::NAN, |v| window_mean(v, true)),
        Quantity::TrainingLast(o) => d.orders.get(o.name()).map_or(f64::NAN, |v| window_mean(v, false)),
        Quantity::EvalDos(e) => eval(e, Order::Dos),
        Quantity::EvalDoa(e) => eval(e, Order::Doa),
        Quantity::EvalOrder(e, Order::EdgeRank) => d.evals.get(e).map_or(f64::NAN, |x| x.edge_rank),
        Quantity::EvalOrder(e, o) => eval(e, *o),
        Quantity::EvalCatches(e) => d.evals.get(e).map_or(f64::NAN, |x| x.catches_per_prey),
        Quantity::Reach90(name) => reach90(if *name == Curve::Dos { &d.dos } else { &d.doa }),
        Quantity::Start(o)
        | Quantity::Extreme(o)
        | Quantity::ExtremeEpisode(o)
        | Quantity::AfterExtreme(o)
        | Quantity::Halfway(o)
        | Quantity::Reaches(o, _)
        | Quantity::Fitted(o, _) => {
            let series = match o {
                Curve::Dos => &d.dos,
                Curve::Doa => &d.doa,
                Curve::Catches => &d.catches,
                // The authors' DoS and DoA (`authors_metrics`), loaded beside the order parameters.
                Curve::AuthorsDos | Curve::AuthorsDoa => d.orders.get(o.name()).map_or(&[][..], |v| v.as_slice()),
            };
            // At single precision, as figure-data.ron.gz keeps the curve (its `single` values): a summary
            // extended from that file gets the same bits.
            shape_of(q, &series.iter().map(|&x| x as f32 as f64).collect::<Vec<_>>())
        }
        Quantity::Crossplay(name) => d.crossplay.get(name).copied().unwrap_or(f64::NAN),
        Quantity::Distilled(species, form, name) => {
            d.distilled.get(&(species.clone(), *form, name.clone())).copied().unwrap_or(f64::NAN)
        }
        Quantity::Response(e, which) => d.evals.get(e).map_or(f64::NAN, |x| x.response[usize::from(which == "far")]),
        Quantity::Tactic(e, t) => d.evals.get(e).map_or(f64::NAN, |x| x.tactics[t.index()]),
        // Derived from the ones above ([`derive`]): no value of their own. Named, not `_`, so that a new
        // quantity is a compile error here until it is given a value or declared derived.
        Quantity::DosChange
        | Quantity::DoaChange
        | Quantity::CatchesChange
        | Quantity::FromStart(_)
        | Quantity::InteractionDoa(_)
        | Quantity::Interaction(..)
        | Quantity::Learned(..)
        | Quantity::EvalDifference(..)
        | Quantity::TacticLearned(..)
        | Quantity::DistilledDifference(..) => f64::NAN,
    }
}

/// The summary.csv column of a primitive quantity, None for a derived one ([`derive`]): the one place
/// these names are made.
pub(crate) fn column(q: &Quantity) -> Option<String> {
    Some(match q {
        Quantity::DosFirst => "dos_first100".into(),
        Quantity::DosLast => "dos_last100".into(),
        Quantity::DoaFirst => "doa_first100".into(),
        Quantity::DoaLast => "doa_last100".into(),
        Quantity::CatchesFirst => "catches_first100".into(),
        Quantity::CatchesLast => "catches_last100".into(),
        Quantity::TrainingFirst(o) => format!("{o}_first100"),
        Quantity::TrainingLast(o) => format!("{o}_last100"),
        Quantity::Reach90(o) => format!("{o}_reach90"),
        Quantity::Start(o) => format!("{o}_start{START}"),
        Quantity::Extreme(o) => format!("{o}_{}", extreme_word(*o)),
        Quantity::ExtremeEpisode(o) => format!("{o}_{}_episode", extreme_word(*o)),
        Quantity::AfterExtreme(o) => format!("{o}_after_{}", extreme_word(*o)),
        Quantity::Halfway(o) => format!("{o}_halfway"),
        Quantity::Reaches(o, level) => format!("{o}_reaches_{level}"),
        Quantity::Fitted(o, part) => format!("{o}_fitted_{}", format!("{part:?}").to_lowercase()),
        Quantity::EvalDos(e) => format!("eval_{}_dos_settled", super::file::slug(e)),
        Quantity::EvalDoa(e) => format!("eval_{}_doa_settled", super::file::slug(e)),
        Quantity::EvalOrder(e, o) => format!("eval_{}_{o}", super::file::slug(e)),
        Quantity::EvalCatches(e) => format!("eval_{}_catches_per_prey", super::file::slug(e)),
        Quantity::Crossplay(name) => format!("crossplay_{name}"),
        Quantity::Distilled(species, form, name) => {
            format!("distilled_{species}_{}_{}", format!("{form:?}").to_lowercase(), name.replace('.', "_"))
        }
        Quantity::Response(e, which) => format!("eval_{}_response_{which}", super::file::slug(e)),
        Quantity::Tactic(e, t) => format!("eval_{}_{}", super::file::slug(e), t.column()),
        // Derived ([`derive`]): summary.csv holds what they are computed from (and, for the interactions,
        // a column `summary::columns` names itself).
        Quantity::DosChange
        | Quantity::DoaChange
        | Quantity::CatchesChange
        | Quantity::FromStart(_)
        | Quantity::InteractionDoa(_)
        | Quantity::Interaction(..)
        | Quantity::Learned(..)
        | Quantity::EvalDifference(..)
        | Quantity::TacticLearned(..)
        | Quantity::DistilledDifference(..) => return None,
    })
}

/// Every quantity from primitive ones (`primitive` gives those): the one definition of each derived
/// quantity, for a run's files ([`quantity`]), for summary.csv (`summary::Summary::quantity`) and for
/// curves made elsewhere ([`super::external`]) alike. `evaluations`: the experiment's, which the
/// quantities of a control or an untrained evaluation find their partner among (none for training curves).
pub(crate) fn derive(
    evaluations: &[super::file::Evaluation],
    q: &Quantity,
    primitive: &dyn Fn(&Quantity) -> f64,
) -> f64 {
    // An order parameter of an evaluation: DoS and DoA settled, the others as EvalOrder has them.
    let of_eval = |e: &str, o: Order| match o {
        Order::Dos => primitive(&Quantity::EvalDos(e.into())),
        Order::Doa => primitive(&Quantity::EvalDoa(e.into())),
        Order::Catches => primitive(&Quantity::EvalCatches(e.into())),
        // Refused in these quantities when the file is loaded (`Order::compared`).
        Order::AuthorsDos | Order::AuthorsDoa => f64::NAN,
        Order::Polarization
        | Order::Milling
        | Order::Clusters
        | Order::LargestCluster
        | Order::NnCorrelation
        | Order::EdgeRank => primitive(&Quantity::EvalOrder(e.into(), o)),
    };
    let seeing = |e: &str| super::file::seeing_partner(evaluations, e).map(|s| s.name.clone());
    match q {
        Quantity::DosChange => primitive(&Quantity::DosLast) - primitive(&Quantity::DosFirst),
        Quantity::DoaChange => primitive(&Quantity::DoaLast) - primitive(&Quantity::DoaFirst),
        Quantity::CatchesChange => primitive(&Quantity::CatchesLast) - primitive(&Quantity::CatchesFirst),
        Quantity::FromStart(o) => {
            let last = match o {
                Curve::Dos => Quantity::DosLast,
                Curve::Doa => Quantity::DoaLast,
                Curve::Catches => Quantity::CatchesLast,
                Curve::AuthorsDos => Quantity::TrainingLast(Order::AuthorsDos),
                Curve::AuthorsDoa => Quantity::TrainingLast(Order::AuthorsDoa),
            };
            primitive(&last) - primitive(&Quantity::Start(*o))
        }
        Quantity::InteractionDoa(e) => seeing(e).map_or(f64::NAN, |s| of_eval(&s, Order::Doa) - of_eval(e, Order::Doa)),
        Quantity::Interaction(e, o) => seeing(e).map_or(f64::NAN, |s| of_eval(&s, *o) - of_eval(e, *o)),
        Quantity::Learned(e, o) => match super::file::untrained_partner(evaluations, e) {
            Some(untrained) => of_eval(e, *o) - of_eval(&untrained.name, *o),
            None => f64::NAN,
        },
        Quantity::EvalDifference(a, b, o) => of_eval(a, *o) - of_eval(b, *o),
        Quantity::TacticLearned(e, t) => match super::file::untrained_partner(evaluations, e) {
            Some(untrained) => {
                primitive(&Quantity::Tactic(e.clone(), *t)) - primitive(&Quantity::Tactic(untrained.name.clone(), *t))
            }
            None => f64::NAN,
        },
        Quantity::DistilledDifference(species, a, b, name) => {
            let of = |form| primitive(&Quantity::Distilled(species.clone(), form, name.clone()));
            of(*a) - of(*b)
        }
        // Primitive: a run's files or summary.csv hold them. Named, not `_`, so that a new quantity is a
        // compile error here until it is derived or declared primitive.
        Quantity::DosFirst
        | Quantity::DosLast
        | Quantity::DoaFirst
        | Quantity::DoaLast
        | Quantity::CatchesFirst
        | Quantity::CatchesLast
        | Quantity::TrainingFirst(_)
        | Quantity::TrainingLast(_)
        | Quantity::EvalDos(_)
        | Quantity::EvalDoa(_)
        | Quantity::EvalOrder(..)
        | Quantity::EvalCatches(_)
        | Quantity::Reach90(_)
        | Quantity::Start(_)
        | Quantity::Extreme(_)
        | Quantity::ExtremeEpisode(_)
        | Quantity::AfterExtreme(_)
        | Quantity::Halfway(_)
        | Quantity::Reaches(..)
        | Quantity::Fitted(..)
        | Quantity::Response(..)
        | Quantity::Tactic(..)
        | Quantity::Crossplay(_)
        | Quantity::Distilled(..) => primitive(q),
    }
}

/// Which order parameters a quantity takes ([`Order::of_evaluation`], [`Order::of_training`], [`Order::compared`]).
pub(crate) type Takes = fn(Order) -> bool;

/// Each property of a quantity, one exhaustive match each, so that a new quantity is a compile error here
/// until it says what it is: the quantity's variant in `file.rs`, its properties here and, for one that
/// reads new numbers of a run, where they are read (`results.rs`, `experiment/data.rs`).
impl Quantity {
    /// The training curve and the number of its shape this quantity reads ([`curve_shape`]), None for
    /// another quantity.
    pub(crate) fn shape(&self) -> Option<(Curve, Shape)> {
        match self {
            Quantity::Start(c) => Some((*c, Shape::Start)),
            Quantity::Halfway(c) => Some((*c, Shape::Halfway)),
            Quantity::Reaches(c, level) => Some((*c, Shape::Reaches(*level))),
            Quantity::Fitted(c, part) => Some((*c, Shape::Fitted(*part))),
            Quantity::Extreme(c) => Some((*c, Shape::Extreme)),
            Quantity::ExtremeEpisode(c) => Some((*c, Shape::ExtremeEpisode)),
            Quantity::AfterExtreme(c) => Some((*c, Shape::AfterExtreme)),
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::FromStart(_)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => None,
        }
    }

    /// Why a training-curve quantity does not take the curve it names (the curves each takes), None when it
    /// does or is another quantity: the one check of experiment files (`experiment::load`) and of curves made
    /// elsewhere (`experiment::external`).
    pub(crate) fn curve_argument_error(&self) -> Option<String> {
        match self {
            // Start and FromStart take every curve; the others DoS and DoA (Fitted catches too).
            Quantity::Extreme(c) | Quantity::ExtremeEpisode(c) | Quantity::AfterExtreme(c) if !c.is_order() => {
                Some(format!("Extreme, ExtremeEpisode and AfterExtreme take \"dos\" or \"doa\" (got {c:?})"))
            }
            Quantity::Reach90(c) if !c.is_order() => Some(format!("Reach90 takes \"dos\" or \"doa\" (got {c:?})")),
            Quantity::Halfway(c) if !c.is_order() => Some(format!("Halfway takes \"dos\" or \"doa\" (got {c:?})")),
            Quantity::Reaches(c, _) if !c.is_order() => {
                Some(format!("Reaches takes \"dos\" or \"doa\" and a level (got {c:?})"))
            }
            Quantity::Fitted(c, _) if !CURVES.contains(c) => {
                Some(format!("Fitted takes \"dos\", \"doa\" or \"catches\" and Start, End or Time (got {c:?})"))
            }
            Quantity::Reaches(_, level) if !(level.is_finite() && *level > 0.0 && *level <= 1.0) => {
                Some(format!("Reaches takes a level in (0, 1], as DoS and DoA are (got {level})"))
            }
            // Every other quantity, and the ones above with the curves they take (named, not `_`: a new
            // quantity is a compile error here until it says whether it takes a curve).
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => None,
        }
    }

    /// The order parameter it is in units of (for a level, and for a difference of two alike), None for a
    /// quantity in other units (an episode, a fitted gain or time, a read-out, radians, a tactic).
    pub(crate) fn order(&self) -> Option<Order> {
        // A training curve in the units of the order parameter it measures.
        let curve = |c: &Curve| match c {
            Curve::Dos | Curve::AuthorsDos => Order::Dos,
            Curve::Doa | Curve::AuthorsDoa => Order::Doa,
            Curve::Catches => Order::Catches,
        };
        match self {
            Quantity::DosFirst | Quantity::DosLast | Quantity::EvalDos(_) | Quantity::DosChange => Some(Order::Dos),
            Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::EvalDoa(_)
            | Quantity::DoaChange
            | Quantity::InteractionDoa(_) => Some(Order::Doa),
            Quantity::Start(c)
            | Quantity::FromStart(c)
            | Quantity::Extreme(c)
            | Quantity::AfterExtreme(c)
            | Quantity::Fitted(c, Fit::Start | Fit::End) => Some(curve(c)),
            Quantity::TrainingFirst(o)
            | Quantity::TrainingLast(o)
            | Quantity::EvalOrder(_, o)
            | Quantity::Interaction(_, o)
            | Quantity::Learned(_, o)
            | Quantity::EvalDifference(_, _, o) => Some(o.measured()),
            Quantity::CatchesFirst | Quantity::CatchesLast | Quantity::CatchesChange | Quantity::EvalCatches(_) => {
                Some(Order::Catches)
            }
            Quantity::Fitted(_, Fit::Time)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => None,
        }
    }

    /// Whether it is a difference within each run (a change over training, what a control or training
    /// removes, one evaluation or form against another), so that a claim on it is an effect, never a level.
    pub(crate) fn is_difference(&self) -> bool {
        match self {
            Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::FromStart(_)
            | Quantity::AfterExtreme(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::TacticLearned(..)
            | Quantity::DistilledDifference(..) => true,
            // A cross-play read-out without a value by chance is a difference of two cells.
            Quantity::Crossplay(r) => super::crossplay_readouts::chance(r).is_none(),
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::Distilled(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..) => false,
        }
    }

    /// Whether it compares the first and last 100 training episodes (meaningless when they overlap).
    pub(crate) fn compares_windows(&self) -> bool {
        match self {
            Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::Reach90(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_) => true,
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Start(_)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => false,
        }
    }

    /// Whether it is computed from the per-episode DoS, DoA and catches alone (what curves made elsewhere
    /// hold, `experiment::external`).
    pub(crate) fn of_training_curves(&self) -> bool {
        match self {
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast => true,
            Quantity::Start(c)
            | Quantity::FromStart(c)
            | Quantity::Reach90(c)
            | Quantity::Halfway(c)
            | Quantity::Reaches(c, _)
            | Quantity::Fitted(c, _)
            | Quantity::Extreme(c)
            | Quantity::ExtremeEpisode(c)
            | Quantity::AfterExtreme(c) => CURVES.contains(c),
            // Evaluations, other order parameters, cross-play, fitted rules and tactics.
            Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => false,
        }
    }

    /// The columns a claim on it adds to `summary.csv` beyond every summary's own
    /// (`summary::columns`): a level some claim times a curve against, a fitted approach, a tactic (and,
    /// for a tactic's change by training, the same in the untrained partner of `evaluations`). Every other
    /// summary keeps its columns.
    pub(crate) fn asked_columns(&self, evaluations: &[super::file::Evaluation]) -> Vec<Quantity> {
        match self {
            Quantity::Reaches(..) | Quantity::Fitted(..) | Quantity::Tactic(..) => vec![self.clone()],
            Quantity::TacticLearned(e, t) => std::iter::once(e.clone())
                .chain(super::file::untrained_partner(evaluations, e).map(|u| u.name.clone()))
                .map(|e| Quantity::Tactic(e, *t))
                .collect(),
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Response(..)
            | Quantity::Crossplay(_) => vec![],
        }
    }

    /// Whether it reads the rules fitted to a run (`distilled.ron`).
    pub(crate) fn reads_rules(&self) -> bool {
        match self {
            Quantity::Distilled(..) | Quantity::DistilledDifference(..) => true,
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => false,
        }
    }

    /// Whether it is the episode a curve converges by (drawn beside the changes in a file's figures).
    pub(crate) fn is_convergence_episode(&self) -> bool {
        match self {
            Quantity::Halfway(_) | Quantity::Reaches(..) => true,
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => false,
        }
    }

    /// The evaluations it reads, by name (each must be one of the file's).
    pub(crate) fn evaluations(&self) -> Vec<&str> {
        match self {
            Quantity::EvalDos(e)
            | Quantity::EvalDoa(e)
            | Quantity::EvalCatches(e)
            | Quantity::EvalOrder(e, _)
            | Quantity::InteractionDoa(e)
            | Quantity::Interaction(e, _)
            | Quantity::Learned(e, _)
            | Quantity::Tactic(e, _)
            | Quantity::TacticLearned(e, _)
            | Quantity::Response(e, _) => vec![e.as_str()],
            Quantity::EvalDifference(a, b, _) => vec![a.as_str(), b.as_str()],
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Crossplay(_) => vec![],
        }
    }

    /// The evaluations whose catches per prey it reads (a column of `summary.csv` only where a claim
    /// reads one), with the untrained partners in `evaluations` of a change by training.
    pub(crate) fn catches_of(&self, evaluations: &[super::file::Evaluation]) -> Vec<String> {
        match self {
            Quantity::EvalCatches(e) => vec![e.clone()],
            Quantity::EvalDifference(a, b, Order::Catches) => vec![a.clone(), b.clone()],
            Quantity::Learned(e, Order::Catches) => std::iter::once(e.clone())
                .chain(super::file::untrained_partner(evaluations, e).map(|u| u.name.clone()))
                .collect(),
            Quantity::EvalDifference(..)
            | Quantity::Learned(..)
            | Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => vec![],
        }
    }

    /// The order parameter it names and whether it takes that one ([`Order::of_evaluation`],
    /// [`Order::of_training`], [`Order::compared`]); None for a quantity that names none.
    pub(crate) fn named_order(&self) -> Option<(Order, Takes)> {
        match self {
            Quantity::EvalOrder(_, o) | Quantity::Interaction(_, o) => Some((*o, Order::of_evaluation)),
            Quantity::TrainingFirst(o) | Quantity::TrainingLast(o) => Some((*o, Order::of_training)),
            Quantity::Learned(_, o) | Quantity::EvalDifference(_, _, o) => Some((*o, Order::compared)),
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => None,
        }
    }

    /// The numbers of fitted rules it reads: (species, form, name) of each.
    pub(crate) fn rules_read(&self) -> Vec<(&str, crate::scene::RuleForm, &str)> {
        match self {
            Quantity::Distilled(species, form, name) => vec![(species.as_str(), *form, name.as_str())],
            Quantity::DistilledDifference(species, a, b, name) => {
                vec![(species.as_str(), *a, name.as_str()), (species.as_str(), *b, name.as_str())]
            }
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::TrainingFirst(_)
            | Quantity::TrainingLast(_)
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Start(_)
            | Quantity::FromStart(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => vec![],
        }
    }

    /// The shipped code's DoS or DoA it reads (`authors_metrics`), by its curve's name; None otherwise.
    pub(crate) fn authors_curve(&self) -> Option<&'static str> {
        let name = match self {
            Quantity::Start(c) | Quantity::FromStart(c) => c.name(),
            Quantity::TrainingFirst(o) | Quantity::TrainingLast(o) => o.name(),
            Quantity::DosFirst
            | Quantity::DosLast
            | Quantity::DoaFirst
            | Quantity::DoaLast
            | Quantity::DosChange
            | Quantity::DoaChange
            | Quantity::CatchesChange
            | Quantity::CatchesFirst
            | Quantity::CatchesLast
            | Quantity::EvalDos(_)
            | Quantity::EvalDoa(_)
            | Quantity::EvalOrder(..)
            | Quantity::EvalCatches(_)
            | Quantity::InteractionDoa(_)
            | Quantity::Interaction(..)
            | Quantity::Learned(..)
            | Quantity::EvalDifference(..)
            | Quantity::Distilled(..)
            | Quantity::DistilledDifference(..)
            | Quantity::Reach90(_)
            | Quantity::Extreme(_)
            | Quantity::ExtremeEpisode(_)
            | Quantity::AfterExtreme(_)
            | Quantity::Halfway(_)
            | Quantity::Reaches(..)
            | Quantity::Fitted(..)
            | Quantity::Response(..)
            | Quantity::Tactic(..)
            | Quantity::TacticLearned(..)
            | Quantity::Crossplay(_) => return None,
        };
        AUTHORS_CURVES.contains(&name).then_some(name)
    }
}

/// A curve quantity's value from its curve's per-episode `series` ([`Quantity::shape`]); NaN for another
/// quantity.
pub(crate) fn shape_of(q: &Quantity, series: &[f64]) -> f64 {
    q.shape().map_or(f64::NAN, |(curve, shape)| super::curves::curve_shape(shape, curve, series))
}

/// The value a level has by chance alone, which a level must be told apart from: the claim's `baseline`,
/// else for DoA 2/π (independent uniform headings) and for DoS the DoS of uniform random positions at the
/// density of `scene` (or of the evaluation's counts). None for other levels and for effects.
pub(crate) fn chance_level(exp: &Experiment, claim: &Claim, scene: Option<&crate::scene::Scene>) -> Option<f64> {
    if claim.baseline.is_some() || is_effect(claim) {
        return claim.baseline;
    }
    // The scene and how many of the headline species there are: in training, or in an evaluation.
    let headline = |evaluation: Option<&str>| {
        let scene = scene?;
        let registry = crate::sim::species::SpeciesRegistry::from_scene(scene);
        let prey = registry.headline();
        let name = &registry.defs[prey].name;
        let counts = evaluation.and_then(|e| exp.spec.evaluations.iter().find(|x| x.name == e));
        let n = counts
            .and_then(|e| e.counts.iter().find(|(s, _)| s == name).map(|(_, n)| *n))
            .unwrap_or(registry.defs[prey].count);
        Some((scene, n))
    };
    let random_dos = |evaluation: Option<&str>| {
        let (scene, n) = headline(evaluation)?;
        let arena = crate::sim::space::Arena { edge: scene.world.arena_edge, boundary: scene.world.boundary };
        crate::sim::metrics::random_dos(&arena, n)
    };
    let random_authors = |curve: &str| {
        let (scene, n) = headline(None)?;
        let which = AUTHORS_CURVES.iter().position(|c| *c == curve)?;
        crate::sim::metrics::random_authors(scene.world.arena_edge, n).map(|v| v[which])
    };
    match &claim.quantity {
        Quantity::DoaFirst | Quantity::DoaLast | Quantity::EvalDoa(_) => Some(std::f64::consts::FRAC_2_PI),
        Quantity::Start(Curve::Doa) | Quantity::Extreme(Curve::Doa) => Some(std::f64::consts::FRAC_2_PI),
        Quantity::DosFirst | Quantity::DosLast => random_dos(None),
        Quantity::Start(Curve::Dos) | Quantity::Extreme(Curve::Dos) => random_dos(None),
        Quantity::EvalDos(e) => random_dos(Some(e)),
        Quantity::Crossplay(r) => super::crossplay_readouts::chance(r),
        // The authors' DoS and DoA of random positions and headings at the training density.
        Quantity::Start(o @ (Curve::AuthorsDos | Curve::AuthorsDoa)) => random_authors(o.name()),
        Quantity::TrainingFirst(o @ (Order::AuthorsDos | Order::AuthorsDoa))
        | Quantity::TrainingLast(o @ (Order::AuthorsDos | Order::AuthorsDoa)) => random_authors(o.name()),
        // Caught prey ranked at random within their group: the mean edge rank of no marginal predation.
        Quantity::EvalOrder(_, Order::EdgeRank)
        | Quantity::TrainingFirst(Order::EdgeRank)
        | Quantity::TrainingLast(Order::EdgeRank) => Some(0.5),
        // Independent headings: no correlation between nearest neighbours.
        Quantity::EvalOrder(_, Order::NnCorrelation)
        | Quantity::TrainingFirst(Order::NnCorrelation)
        | Quantity::TrainingLast(Order::NnCorrelation) => Some(0.0),
        // No value by chance: the other order parameters, timings, and numbers of a fitted rule (effects
        // returned above). Named, not `_`, so that a new quantity says whether chance gives it a value.
        Quantity::DosChange
        | Quantity::DoaChange
        | Quantity::CatchesChange
        | Quantity::CatchesFirst
        | Quantity::CatchesLast
        | Quantity::TrainingFirst(_)
        | Quantity::TrainingLast(_)
        | Quantity::EvalOrder(..)
        | Quantity::EvalCatches(_)
        | Quantity::InteractionDoa(_)
        | Quantity::Interaction(..)
        | Quantity::Learned(..)
        | Quantity::EvalDifference(..)
        | Quantity::TacticLearned(..)
        | Quantity::DistilledDifference(..)
        | Quantity::Reach90(_)
        | Quantity::Start(_)
        | Quantity::FromStart(_)
        | Quantity::Extreme(_)
        | Quantity::ExtremeEpisode(_)
        | Quantity::AfterExtreme(_)
        | Quantity::Halfway(_)
        | Quantity::Reaches(..)
        | Quantity::Fitted(..)
        | Quantity::Response(..)
        | Quantity::Distilled(..) => None,
        // Each is a difference whose 0 is "no such tactic", except the heading to the nearest prey.
        Quantity::Tactic(_, t) => match t {
            super::file::Tactic::SteerNearest => None,
            super::file::Tactic::Slowdown
            | super::file::Tactic::Hesitation
            | super::file::Tactic::CentreEarly
            | super::file::Tactic::CentreChange
            | super::file::Tactic::IsolatedOverNearest
            | super::file::Tactic::BoundaryExcess => Some(0.0),
        },
    }
}

pub(crate) fn quantity_name(q: &Quantity) -> String {
    match q {
        Quantity::DosFirst => "DoS, first 100 episodes".into(),
        Quantity::TrainingFirst(q) => format!("{q}, first 100 episodes"),
        Quantity::TrainingLast(q) => format!("{q}, last 100 episodes"),
        Quantity::DosLast => "DoS, last 100 episodes".into(),
        Quantity::DoaFirst => "DoA, first 100 episodes".into(),
        Quantity::DoaLast => "DoA, last 100 episodes".into(),
        Quantity::DosChange => "DoS change, last − first 100".into(),
        Quantity::DoaChange => "DoA change, last − first 100".into(),
        Quantity::CatchesChange => "catches per episode, change, last − first 100".into(),
        Quantity::CatchesFirst => "catches per episode, first 100".into(),
        Quantity::CatchesLast => "catches per episode, last 100".into(),
        Quantity::Crossplay(r) => format!("cross-play read-out {r}"),
        Quantity::Distilled(species, form, name) => format!("{name} of the {form:?} rule fitted to the {species}"),
        Quantity::Response(e, w) => format!("{w} response to one prey turned, in evaluation \"{e}\" (rad)"),
        Quantity::Tactic(e, t) => format!("{} in evaluation \"{e}\"", t.words()),
        Quantity::TacticLearned(e, t) => {
            format!("{} in evaluation \"{e}\", trained minus untrained actors", t.words())
        }
        Quantity::EvalDos(e) => format!("DoS settled in evaluation \"{e}\""),
        Quantity::EvalDoa(e) => format!("DoA settled in evaluation \"{e}\""),
        Quantity::EvalOrder(e, q) => format!("{q} in evaluation \"{e}\""),
        Quantity::EvalCatches(e) => format!("catches per prey per episode in evaluation \"{e}\""),
        Quantity::InteractionDoa(e) => format!("DoA seeing minus \"{e}\" (interaction-driven alignment)"),
        Quantity::Interaction(e, q) => format!("{q} seeing minus \"{e}\""),
        Quantity::Learned(e, q) => format!("{q} in evaluation \"{e}\", trained minus untrained actors"),
        Quantity::EvalDifference(a, b, q) => format!("{q} in evaluation \"{a}\" minus in \"{b}\""),
        Quantity::DistilledDifference(species, a, b, name) => {
            format!("{name} of the {a:?} rule fitted to the {species} minus of the {b:?} one")
        }
        Quantity::Reach90(q) => format!("episode at which {q}'s running mean completes 90 % of its change"),
        Quantity::Halfway(q) => format!(
            "episode at which {q}'s {HALFWAY_WINDOW}-episode running mean completes half its change from the first {START} episodes"
        ),
        Quantity::Reaches(q, level) => format!(
            "episode at which {q}'s {HALFWAY_WINDOW}-episode running mean first {} {level} (after the run when never)",
            if *q == Curve::Dos { "falls to" } else { "rises to" }
        ),
        Quantity::Fitted(q, part) => match part {
            super::file::Fit::Start => format!("{q}'s fitted start (exponential approach)"),
            super::file::Fit::End => format!("{q}'s fitted end level (exponential approach)"),
            super::file::Fit::Time => format!("{q}'s fitted time constant, episodes (exponential approach)"),
        },
        Quantity::Start(q) => format!("{q}, first {START} episodes (the untrained start)"),
        Quantity::FromStart(q) => format!("{q}, last 100 episodes minus the first {START}"),
        Quantity::Extreme(q) => {
            format!("{q}'s {} 100-episode mean (window chosen on odd episodes, measured on even)", extreme_word(*q))
        }
        Quantity::ExtremeEpisode(q) => format!("episode ending {q}'s {} 100-episode window", extreme_word(*q)),
        Quantity::AfterExtreme(q) => format!("{q}, last 100 episodes minus its {} (even episodes)", extreme_word(*q)),
    }
}
