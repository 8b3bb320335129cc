//! What an eval adds to the mean of its walks: the deterministic terms and a
//! rough coat's sampled part ([`Terms`]), and how the engines compute them.

use super::accumulate::MeanVar;
use super::coat_lambertian::CoatLambertian;
use super::estimate::Estimate;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, Rgb, V3};

/// What an eval adds to the mean of its walks: deterministic terms (the
/// first-order term, a smooth coat's closed form) and, for a rough coat over
/// a Lambertian base, the mean of independent samples of its factorized part
/// (`rough_coat`), whose variance adds to the walks'.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Terms {
    /// Added exactly.
    pub exact: [f64; 3],
    /// Added with its standard error.
    pub sampled: Option<MeanVar>,
}

impl MeanVar {
    /// The estimate of the walks plus `terms`: the means add, and the
    /// variances of the means of independent samples add.
    pub fn estimate_with(&self, terms: &Terms) -> Estimate {
        let mut e = self.estimate_plus(terms.exact);
        if let Some(s) = terms.sampled {
            let x = s.estimate();
            for c in 0..3 {
                e.value[c] += x.value[c];
                e.stderr[c] = e.stderr[c].hypot(x.stderr[c]);
            }
        }
        e
    }
}

/// What an eval adds to its walks, in f64: the first-order term (the
/// entrance alone, when it is also the exit: `same`), plus, with the control
/// variate `cv`, the part of `f` its walks leave out at the walks' directions
/// (taken from the engine's precision, so that both engines add the same
/// numbers): a smooth coat's closed form exactly, a rough coat's
/// factorized part as the mean of `n` samples from the query's streams
/// (`prefix`). A smooth coat's first-order term is a delta, 0 here, and not
/// a path of `f₀` (which enters the coat); a rough coat's is the coat
/// reflection of `f₀`, which `cv` leaves to this term: nothing is counted
/// twice.
pub fn eval_terms<S: Lane>(
    entrance: &InterfaceLanes<S>,
    same: bool,
    cv: Option<&CoatLambertian>,
    wi: V3<S>,
    wo: V3<S>,
    n: u64,
    prefix: u64,
) -> Terms {
    let lane0 = |c: Rgb<S>| [c.r.lane(0), c.g.lane(0), c.b.lane(0)];
    let direct = if same {
        lane0(entrance.eval(wi, wo))
    } else {
        [0.0; 3]
    };
    let Some(cv) = cv else {
        return Terms {
            exact: direct,
            sampled: None,
        };
    };
    let dir = |v: V3<S>| [v.x.lane(0), v.y.lane(0), v.z.lane(0)];
    let f0 = cv.exact(dir(wi), dir(wo));
    Terms {
        exact: std::array::from_fn(|c| direct[c] + f0[c]),
        sampled: cv.sampled(dir(wi), dir(wo), n, prefix),
    }
}
