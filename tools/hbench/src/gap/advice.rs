//! What to measure next: when the leading hypotheses cannot be told apart on the record,
//! or none is accepted, simulate the two leading fitted models under each experiment the
//! tool knows and say which would separate them best at the record's noise.

use hbmodel::Params;
use serde::Serialize;

use super::drive::simulate;
use super::hide::{measure, Kind};

/// Expected separation of two models by one experiment.
#[derive(Debug, Clone, Serialize)]
pub struct Separation {
    pub experiment: String,
    /// Sum over the record of the squared differences of the two models' noise-free y, P1
    /// and P2, each in units of the record's noise: the chi-square by which data of one
    /// would reject the other.
    pub chi2: f64,
    /// RMS of the same differences (1: the two differ by the noise, sample by sample).
    pub gap: f64,
}

/// The advice: which experiment separates `a` from `b` best.
#[derive(Debug, Clone, Serialize)]
pub struct Advice {
    pub between: [String; 2],
    pub experiments: Vec<Separation>,
    pub best: String,
    pub statement: String,
}

/// Seed of the advice's experiments (their noise is not used: the models are compared
/// noise-free; the seed only fixes the drive's realisation).
const SEED: u64 = 1;

/// A chi-square difference above this separates two models decisively: 2 ln 10 is a
/// Bayes factor of 10 (see `evidence::DECISIVE_RATIO`), taken four times over so that one
/// record of the recommended experiment does it with the fits' own uncertainty on top.
const SEPARATES: f64 = 8.0 * std::f64::consts::LN_10;

/// Compare the models `a` and `b` (labelled) under each known experiment at `noise`
/// (signal, standard deviation).
pub fn advise(
    labels: [&str; 2],
    a: &Params,
    b: &Params,
    noise: &[(&'static str, f64)],
) -> Result<Advice, String> {
    let mut experiments = Vec::new();
    for kind in Kind::ALL {
        let (e, m) = measure(a, kind, SEED)?;
        let (sa, sb) = (simulate(a, &e, &m)?, simulate(b, &e, &m)?);
        let (mut chi2, mut count) = (0.0, 0usize);
        for (name, sigma) in noise {
            if let (Some(x), Some(y)) = (sa.get(name), sb.get(name)) {
                chi2 += x
                    .iter()
                    .zip(y)
                    .map(|(x, y)| ((x - y) / sigma).powi(2))
                    .sum::<f64>();
                count += x.len();
            }
        }
        experiments.push(Separation {
            experiment: kind.name().into(),
            chi2,
            gap: (chi2 / count.max(1) as f64).sqrt(),
        });
    }
    let best = experiments
        .iter()
        .max_by(|x, y| x.chi2.total_cmp(&y.chi2))
        .expect("four experiments");
    let statement = if best.chi2 >= SEPARATES {
        format!(
            "to tell {} from {}, record the {} experiment: the two differ there by a chi-square of {:.0} at this record's noise (RMS {:.2} x the noise)",
            labels[0], labels[1], best.experiment, best.chi2, best.gap
        )
    } else {
        format!(
            "none of the known experiments tells {} from {} (best: {}, chi-square {:.1} at this record's noise); a longer or larger experiment is needed",
            labels[0], labels[1], best.experiment, best.chi2
        )
    };
    Ok(Advice {
        between: [labels[0].into(), labels[1].into()],
        best: best.experiment.clone(),
        experiments,
        statement,
    })
}
