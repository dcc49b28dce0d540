//! The main job on the built-in thesis parameters: the section 4.4 step responses and the
//! mode-1 closed-loop sweep with and without the manifold, written to `out/` as CSV, an
//! SVG plot and a JSON summary.
use hbmodel::control::{
    response_time_95, run_closed_loop, sine_amplitude_ratio, Proportional, SAMPLE_PERIOD,
};
use hbmodel::params::ValveModel;
use hbmodel::{Effect, Mode, Params, Simulation};
use std::fmt::Write;

fn ratio(p: &Params, f: f64) -> f64 {
    sine_amplitude_ratio(p, 1169.0, 3.4e-3, f).expect("the bench integrates")
}

/// (label, colour, (frequency, ratio) points)
type Curve<'a> = (&'a str, &'a str, Vec<(f64, f64)>);

fn svg(curves: &[Curve]) -> String {
    let (w, h, m) = (640.0, 400.0, 50.0);
    let fx = |f: f64| m + (f.log10() - 1.0) / (2.7 - 1.0) * (w - 2.0 * m);
    let db = |r: f64| 20.0 * r.log10();
    let fy = |d: f64| m + (10.0 - d) / 60.0 * (h - 2.0 * m);
    let mut s = format!("<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='12'>\n");
    let _ = writeln!(s, "<rect width='{w}' height='{h}' fill='white'/><text x='{m}' y='20'>Mode 1, closed loop (Kp = 1169 V/m), 3.4 mm sine: |Y/Yref| (dB) vs frequency (Hz)</text>");
    for f in [10.0, 20.0, 50.0, 100.0, 200.0, 500.0] {
        let _ = writeln!(s, "<line x1='{0}' y1='{m}' x2='{0}' y2='{1}' stroke='#ddd'/><text x='{0}' y='{2}'>{f}</text>", fx(f), h - m, h - m + 15.0);
    }
    for d in [-50.0, -40.0, -30.0, -20.0, -10.0, 0.0, 10.0] {
        let _ = writeln!(s, "<line x1='{m}' y1='{0}' x2='{1}' y2='{0}' stroke='#ddd'/><text x='10' y='{0}'>{d}</text>", fy(d), w - m);
    }
    for (k, (name, color, pts)) in curves.iter().enumerate() {
        let path: Vec<String> = pts
            .iter()
            .map(|(f, r)| format!("{:.1},{:.1}", fx(*f), fy(db(*r))))
            .collect();
        let _ = writeln!(
            s,
            "<polyline fill='none' stroke='{color}' stroke-width='2' points='{}'/>",
            path.join(" ")
        );
        let _ = writeln!(
            s,
            "<text x='{}' y='{}' fill='{color}'>{name}</text>",
            w - 260.0,
            m + 20.0 + 16.0 * k as f64
        );
    }
    s + "</svg>\n"
}

fn main() -> std::io::Result<()> {
    let out = std::path::Path::new("out");
    std::fs::create_dir_all(out)?;
    let mut summary = String::from("{\n  \"step_95_percent_time_s\": {");
    for (k, mode) in Mode::ALL.iter().enumerate() {
        let mut p = Params::thesis_bench(*mode);
        p.initial_position = -0.01;
        let mut sim = Simulation::new(&p).expect("valid parameters");
        let tr = run_closed_loop(
            &mut sim,
            &mut Proportional { kp: 1169.0 },
            &|_| 0.01,
            0.15,
            SAMPLE_PERIOD,
            10,
        )
        .expect("the bench integrates");
        let t95 = response_time_95(&tr, 0.0, -0.01, 0.01).unwrap_or(f64::NAN);
        let thesis = [0.058, 0.028, 0.055][k];
        println!(
            "mode {}: 95 % step time {t95:.4} s (bench: {thesis} s)",
            mode.number()
        );
        let _ = write!(
            summary,
            "{}\"mode{}\": {t95:.4}",
            if k > 0 { ", " } else { "" },
            mode.number()
        );
    }
    summary.push_str("},\n");
    let with = Params::thesis_bench(Mode::FourWaySingle);
    let mut without = with.clone();
    for e in [
        Effect::ManifoldVolume,
        Effect::ManifoldInertia,
        Effect::ManifoldLosses,
    ] {
        without.effects.set(e, false);
    }
    let freqs: Vec<f64> = (0..60)
        .map(|k| 10.0 * 1.07f64.powi(k))
        .filter(|f| *f < 460.0)
        .collect();
    // the same bench with the two-stage valve model of chapter 2 (issue 3)
    let mut two_stage = with.clone();
    two_stage.sv1.model = ValveModel::TwoStage;
    two_stage.sv2.model = ValveModel::TwoStage;
    let mut csv = String::from(
        "frequency_hz,ratio_with_manifold,ratio_without_manifold,ratio_two_stage_valve\n",
    );
    let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
    for f in &freqs {
        let (ra, rb, rc) = (ratio(&with, *f), ratio(&without, *f), ratio(&two_stage, *f));
        let _ = writeln!(csv, "{f:.3},{ra:.6},{rb:.6},{rc:.6}");
        a.push((*f, ra));
        b.push((*f, rb));
        c.push((*f, rc));
    }
    let part = c
        .iter()
        .zip(&a)
        .find(|(x, y)| (x.1 / y.1 - 1.0).abs() > 0.1)
        .map(|(x, _)| x.0)
        .unwrap_or(f64::NAN);
    println!("two-stage and reduced valves part by more than 10 % from {part:.0} Hz");
    let peak = |c: &[(f64, f64)]| {
        c.iter()
            .filter(|p| p.0 > 60.0)
            .max_by(|x, y| x.1.total_cmp(&y.1))
            .map(|p| p.0)
            .unwrap_or(f64::NAN)
    };
    let (pa, pb) = (peak(&a), peak(&b));
    println!("mode 1 closed-loop resonance peak: {pa:.0} Hz with the manifold, {pb:.0} Hz without");
    let _ = write!(
        summary,
        "  \"sweep_peak_hz\": {{\"with_manifold\": {pa:.1}, \"without_manifold\": {pb:.1}, \"two_stage_valve\": {:.1}}},\n  \"two_stage_parts_from_hz\": {part:.1}\n}}\n",
        peak(&c)
    );
    std::fs::write(out.join("sweep_mode1.csv"), csv)?;
    std::fs::write(
        out.join("sweep_mode1.svg"),
        svg(&[
            ("with manifold", "#c0392b", a),
            ("without manifold", "#2c3e50", b),
            ("with manifold, two-stage valves", "#27ae60", c),
        ]),
    )?;
    std::fs::write(out.join("summary.json"), summary)?;
    println!("wrote out/sweep_mode1.csv, out/sweep_mode1.svg, out/summary.json");
    Ok(())
}
