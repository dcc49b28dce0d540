//! The two-stage servovalve in the bench agrees with the reduced one where the thesis
//! says the valve dynamics do not matter (issue 3): below 50 Hz in closed loop.

use hbmodel::control::sine_amplitude_ratio;
use hbmodel::params::{Mode, Params, ValveModel};

#[test]
fn closed_loop_sweep_below_50_hz_matches_the_reduced_valve_within_10_percent() {
    let reduced = Params::thesis_bench(Mode::FourWaySingle);
    let mut two_stage = reduced.clone();
    two_stage.sv1.model = ValveModel::TwoStage;
    two_stage.sv2.model = ValveModel::TwoStage;
    for f in [10.0, 20.0, 40.0] {
        let a = sine_amplitude_ratio(&reduced, 1169.0, 3.4e-3, f).unwrap();
        let b = sine_amplitude_ratio(&two_stage, 1169.0, 3.4e-3, f).unwrap();
        assert!(
            (b / a - 1.0).abs() < 0.10,
            "{f} Hz: two-stage {b:.4} vs reduced {a:.4}"
        );
    }
}
