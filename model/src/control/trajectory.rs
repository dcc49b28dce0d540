//! The reference trajectory of chapters 5 to 7: 7th-order polynomial moves (section 5.5).
//!
//! The thesis only says that the reference is a 7th-order polynomial between -10 mm and
//! +10 mm whose velocity, acceleration and jerk are smooth, and that the piston velocity
//! stays below 0.3 m/s (section 6.5). The polynomial of degree 7 is the lowest one that
//! can impose position, velocity, acceleration and jerk at both ends of a move: with the
//! three derivatives zero at both ends it is unique,
//!
//!   s(tau) = 35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7,  tau = (t - t0) / T in [0, 1],
//!
//! so that the backstepping laws (which need y_d up to its third derivative) and the
//! restricted-model feedforward (6.11) (which needs the jerk) never see a step.

/// Peak of ds/dtau of the normalised move, reached at mid-move: 140 / 2^6.
pub const PEAK_SPEED_FACTOR: f64 = 35.0 / 16.0;

/// Position of the thesis cycle's low and high plateaus (m), section 5.5.
pub const THESIS_LOW: f64 = -10e-3;
pub const THESIS_HIGH: f64 = 10e-3;

/// Duration of each move of the thesis cycle (s). Not printed in the thesis. 0.2 s puts
/// the peak velocity at 35/16 * 0.02 / 0.2 = 0.219 m/s, 27 % under the 0.3 m/s bound of
/// section 6.5, and the mid-move (peak command) instant at 1.1 s, where the zoomed inset
/// of figure 7.4 looks at the command.
pub const THESIS_MOVE_DURATION: f64 = 0.2;

/// Start of the rising edge (s): figures 5.5, 6.3, 6.4 show the edge inside 0.85-1.35 s.
pub const THESIS_FIRST_MOVE: f64 = 1.0;

/// Time between the starts of the rising and falling edges (s): the plateaus last long
/// enough for the static errors that tables 7.1-7.2 report to settle.
pub const THESIS_HALF_PERIOD: f64 = 1.0;

/// Time slack (s) in checking that moves do not overlap.
const TIME_TOLERANCE: f64 = 1e-9;

/// One move from `from` to `to` (m), starting at `start` and lasting `duration` (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    pub start: f64,
    pub from: f64,
    pub to: f64,
    pub duration: f64,
}

impl Move {
    pub fn new(start: f64, from: f64, to: f64, duration: f64) -> Self {
        Self {
            start,
            from,
            to,
            duration,
        }
    }

    fn end(&self) -> f64 {
        self.start + self.duration
    }

    /// Peak absolute velocity of the move (m/s).
    pub fn peak_speed(&self) -> f64 {
        PEAK_SPEED_FACTOR * (self.to - self.from).abs() / self.duration
    }

    /// y, dy, d2y, d3y at time t, which must lie in [start, start + duration].
    fn eval(&self, t: f64) -> [f64; 4] {
        if t >= self.end() {
            return [self.to, 0.0, 0.0, 0.0];
        }
        let d = self.to - self.from;
        let tt = self.duration;
        let x = ((t - self.start) / tt).clamp(0.0, 1.0);
        let x2 = x * x;
        let x3 = x2 * x;
        let x4 = x3 * x;
        let om = 1.0 - x;
        let s = x4 * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x)));
        // factored forms of the derivatives keep the ends exactly zero
        let s1 = 140.0 * x3 * om * om * om;
        let s2 = 420.0 * x2 * om * om * (1.0 - 2.0 * x);
        let s3 = 840.0 * x * om * (1.0 - 5.0 * x + 5.0 * x2);
        [
            self.from + d * s,
            d * s1 / tt,
            d * s2 / (tt * tt),
            d * s3 / (tt * tt * tt),
        ]
    }
}

/// What is wrong with a list of moves.
#[derive(Debug, Clone, PartialEq)]
pub enum TrajectoryError {
    Empty,
    /// Move `index` has a non-positive or non-finite duration.
    Duration {
        index: usize,
    },
    /// Move `index` starts before the previous one ends.
    Overlap {
        index: usize,
    },
    /// Move `index` does not start where the previous one ended.
    Discontinuous {
        index: usize,
    },
    /// A repeating cycle must end where it started and be longer than its moves.
    Cycle,
}

impl std::fmt::Display for TrajectoryError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Empty => write!(f, "trajectory has no move"),
            Self::Duration { index } => write!(f, "move {index}: duration must be > 0"),
            Self::Overlap { index } => write!(f, "move {index} starts before the previous ends"),
            Self::Discontinuous { index } => {
                write!(
                    f,
                    "move {index} does not start where the previous one ended"
                )
            }
            Self::Cycle => write!(
                f,
                "a repeating cycle must return to its start and outlast its moves"
            ),
        }
    }
}

impl std::error::Error for TrajectoryError {}

/// A sequence of 7th-order moves separated by holds, optionally repeated.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    moves: Vec<Move>,
    /// Repetition period (s) counted from the first move's start.
    period: Option<f64>,
}

impl Trajectory {
    /// Moves as (start time, from, to, duration), in time order. Before the first move the
    /// position holds its `from`; between and after moves it holds the last `to`.
    pub fn new(moves: &[(f64, f64, f64, f64)]) -> Result<Self, TrajectoryError> {
        let moves: Vec<Move> = moves
            .iter()
            .map(|&(s, a, b, d)| Move::new(s, a, b, d))
            .collect();
        Self::check(&moves)?;
        Ok(Self {
            moves,
            period: None,
        })
    }

    /// The same moves repeated every `period` seconds from the first move's start; the
    /// last move must end at the first move's `from` and before the next cycle begins.
    pub fn repeating(moves: &[(f64, f64, f64, f64)], period: f64) -> Result<Self, TrajectoryError> {
        let mut tr = Self::new(moves)?;
        let first = tr.moves[0];
        let last = tr.moves[tr.moves.len() - 1];
        if !(period.is_finite() && last.end() <= first.start + period && last.to == first.from) {
            return Err(TrajectoryError::Cycle);
        }
        tr.period = Some(period);
        Ok(tr)
    }

    /// The test cycle of chapters 5-7: hold -10 mm, rise to +10 mm at 1 s, hold, fall back
    /// at 2 s, hold, and so on every 2 s.
    pub fn thesis() -> Self {
        let t0 = THESIS_FIRST_MOVE;
        let d = THESIS_MOVE_DURATION;
        Self::repeating(
            &[
                (t0, THESIS_LOW, THESIS_HIGH, d),
                (t0 + THESIS_HALF_PERIOD, THESIS_HIGH, THESIS_LOW, d),
            ],
            2.0 * THESIS_HALF_PERIOD,
        )
        .expect("thesis cycle is consistent")
    }

    fn check(moves: &[Move]) -> Result<(), TrajectoryError> {
        if moves.is_empty() {
            return Err(TrajectoryError::Empty);
        }
        for (i, m) in moves.iter().enumerate() {
            if !(m.duration.is_finite() && m.duration > 0.0) {
                return Err(TrajectoryError::Duration { index: i });
            }
            if i > 0 {
                let p = moves[i - 1];
                // tolerance: a move starting at `start + duration` of the previous one
                // in decimal seconds may fall a rounding error before its end
                if m.start < p.end() - TIME_TOLERANCE {
                    return Err(TrajectoryError::Overlap { index: i });
                }
                if m.from != p.to {
                    return Err(TrajectoryError::Discontinuous { index: i });
                }
            }
        }
        Ok(())
    }

    pub fn moves(&self) -> &[Move] {
        &self.moves
    }

    /// Highest absolute velocity over the whole trajectory (m/s).
    pub fn peak_speed(&self) -> f64 {
        self.moves.iter().map(Move::peak_speed).fold(0.0, f64::max)
    }

    /// y_d and its first three derivatives at time t (m, m/s, m/s2, m/s3).
    pub fn at(&self, t: f64) -> [f64; 4] {
        let first = self.moves[0];
        let t = match self.period {
            Some(p) if t >= first.start => first.start + (t - first.start).rem_euclid(p),
            _ => t,
        };
        // last move that has started; before the first one the trajectory holds its origin
        let i = self.moves.partition_point(|m| m.start <= t);
        if i == 0 {
            return [first.from, 0.0, 0.0, 0.0];
        }
        let m = self.moves[i - 1];
        if t >= m.end() {
            [m.to, 0.0, 0.0, 0.0]
        } else {
            m.eval(t)
        }
    }

    /// The reference a [`super::law::Law`] receives (no pressure reference).
    pub fn reference(&self, t: f64) -> super::law::Reference {
        super::law::Reference {
            y: self.at(t),
            p: [0.0, 0.0],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAX_SPEED: f64 = 0.3;

    #[test]
    fn endpoints_are_exact_and_derivatives_vanish() {
        let tr = Trajectory::thesis();
        for m in tr.moves() {
            let a = m.eval(m.start);
            let b = m.eval(m.end());
            assert_eq!(a, [m.from, 0.0, 0.0, 0.0]);
            assert_eq!(b, [m.to, 0.0, 0.0, 0.0]);
        }
        assert_eq!(tr.at(0.0), [THESIS_LOW, 0.0, 0.0, 0.0]);
        assert_eq!(tr.at(1.5), [THESIS_HIGH, 0.0, 0.0, 0.0]);
        assert_eq!(tr.at(2.5), [THESIS_LOW, 0.0, 0.0, 0.0]);
        // repeated cycle
        assert_eq!(tr.at(5.0), [THESIS_LOW, 0.0, 0.0, 0.0]);
        assert_eq!(tr.at(5.2), [THESIS_HIGH, 0.0, 0.0, 0.0]);
        let mid = tr.at(1.1);
        assert!(mid[0].abs() < 1e-15, "mid-move position {}", mid[0]);
        assert!((mid[1] - tr.peak_speed()).abs() < 1e-12);
        assert!((tr.at(7.1)[1] - mid[1]).abs() < 1e-9);
    }

    #[test]
    fn continuous_to_jerk_at_boundaries() {
        let tr = Trajectory::new(&[
            (0.1, -0.01, 0.01, 0.2),
            (0.3, 0.01, 0.0, 0.15),
            (0.6, 0.0, -0.01, 0.25),
        ])
        .unwrap();
        let eps = 1e-9;
        for m in tr.moves() {
            for tb in [m.start, m.end()] {
                let l = tr.at(tb - eps);
                let r = tr.at(tb + eps);
                // scale of each derivative: D/T^k
                let d = (m.to - m.from).abs();
                for k in 0..4 {
                    let scale = d / m.duration.powi(k as i32);
                    // a jump would be O(scale); smoothness leaves O(scale * (eps/T)^(4-k))
                    assert!(
                        (l[k] - r[k]).abs() < 1e-4 * scale,
                        "derivative {k} jumps at t={tb}: {} vs {}",
                        l[k],
                        r[k]
                    );
                }
            }
        }
    }

    #[test]
    fn derivatives_are_consistent() {
        // each derivative is the time derivative of the previous one (central differences)
        let tr = Trajectory::thesis();
        let h = 1e-6;
        for k in 0..=200 {
            let t = 0.99 + k as f64 * 0.22 / 200.0;
            let a = tr.at(t - h);
            let b = tr.at(t + h);
            let c = tr.at(t);
            for j in 0..3 {
                let fd = (b[j] - a[j]) / (2.0 * h);
                let scale = [0.3, 10.0, 200.0][j];
                assert!(
                    (fd - c[j + 1]).abs() < 1e-5 * scale,
                    "t={t} d{j}: fd {fd} vs {}",
                    c[j + 1]
                );
            }
        }
    }

    #[test]
    fn speed_stays_below_bound() {
        let tr = Trajectory::thesis();
        let mut vmax: f64 = 0.0;
        for k in 0..=40_000 {
            let t = k as f64 * 1e-4;
            let [y, v, _, _] = tr.at(t);
            vmax = vmax.max(v.abs());
            assert!((THESIS_LOW..=THESIS_HIGH).contains(&y), "y={y} at {t}");
        }
        assert!(vmax <= MAX_SPEED * 0.8, "peak speed {vmax}");
        assert!((vmax - tr.peak_speed()).abs() < 1e-6);
    }

    #[test]
    fn rejects_inconsistent_moves() {
        assert_eq!(Trajectory::new(&[]), Err(TrajectoryError::Empty));
        assert_eq!(
            Trajectory::new(&[(0.0, 0.0, 1.0, 0.0)]),
            Err(TrajectoryError::Duration { index: 0 })
        );
        assert_eq!(
            Trajectory::new(&[(0.0, 0.0, 1.0, 1.0), (0.5, 1.0, 0.0, 1.0)]),
            Err(TrajectoryError::Overlap { index: 1 })
        );
        assert_eq!(
            Trajectory::new(&[(0.0, 0.0, 1.0, 1.0), (2.0, 0.5, 0.0, 1.0)]),
            Err(TrajectoryError::Discontinuous { index: 1 })
        );
        assert_eq!(
            Trajectory::repeating(&[(0.0, 0.0, 1.0, 1.0)], 2.0),
            Err(TrajectoryError::Cycle)
        );
    }
}
