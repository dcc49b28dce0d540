//! The optimiser's view of a bounded parameter.

use hbmodel::params::param;

use super::Fitted;

/// A log parameter's floor when its registry floor is none (0): this fraction of the
/// low end of its plausible range, three decades under it, so the log scale has a
/// positive floor the data can reach as "practically none".
pub(super) const LOG_FLOOR_OF_NONE: f64 = 1e-3;

/// A bounded parameter seen by the optimiser as an unbounded z: theta = lo + (hi - lo)
/// s(z), s the logistic, on a log scale for the log parameters.
pub(super) struct Coordinate {
    pub(super) fitted: Fitted,
    pub(super) lo: f64,
    pub(super) hi: f64,
}

impl Coordinate {
    /// The coordinate of `f`, within its fit's bounds or the registry's physical ones.
    pub(super) fn new(f: &Fitted) -> Self {
        let spec = param(f.path).expect("candidates use registry parameters");
        let [mut lo, hi] = f.bounds.unwrap_or([spec.min, spec.max]);
        if f.log {
            // a log scale needs a positive floor
            lo = lo.max(f.plausible[0] * LOG_FLOOR_OF_NONE);
        }
        Coordinate { fitted: *f, lo, hi }
    }

    /// The bounds and `v` on the scale the logistic spans (log for a log parameter).
    pub(super) fn scale(&self, v: f64) -> (f64, f64, f64) {
        if self.fitted.log {
            (self.lo.ln(), self.hi.ln(), v.max(self.lo).ln())
        } else {
            (self.lo, self.hi, v)
        }
    }

    /// The parameter's value at coordinate `z`.
    pub(super) fn value(&self, z: f64) -> f64 {
        let (a, b, _) = self.scale(self.lo);
        let w = a + (b - a) / (1.0 + (-z).exp());
        if self.fitted.log {
            w.exp()
        } else {
            w
        }
    }

    /// The coordinate of value `v`, kept a millionth of the span inside the bounds.
    pub(super) fn coordinate(&self, v: f64) -> f64 {
        let (a, b, w) = self.scale(v);
        let s = ((w - a) / (b - a)).clamp(1e-6, 1.0 - 1e-6);
        (s / (1.0 - s)).ln()
    }
}
