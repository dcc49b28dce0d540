//! Grid search that chose `TUNED_DYNAMICS` of the reduced servovalve: prints the
//! (natural frequency, rate limit, damping) triples whose -3 dB frequencies fall within
//! 6 % of 310 Hz at 40 % and 160 Hz at 90 % input.
use hbmodel::params::ValveParams;
use hbmodel::servovalve::reduced::*;
fn main() {
    for fnat in [350.0, 380.0, 410.0, 440.0, 470.0] {
        for r in [450.0, 500.0, 550.0, 600.0, 650.0] {
            for z in [0.6, 0.7] {
                let p = ValveParams {
                    natural_frequency: 2.0 * std::f64::consts::PI * fnat,
                    max_spool_rate: r,
                    damping: z,
                    ..ValveParams::default()
                };
                let v = ReducedServovalve::new(&p, true, true, 1.0);
                let (a, b) = (spool_bandwidth(&v, 0.4), spool_bandwidth(&v, 0.9));
                if (a / 310.0 - 1.0).abs() < 0.06 && (b / 160.0 - 1.0).abs() < 0.06 {
                    println!("fn={fnat} R={r} z={z}: f40={a:.0} f90={b:.0}");
                }
            }
        }
    }
}
