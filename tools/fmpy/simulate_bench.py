#!/usr/bin/env python3
"""A 10 mm position step of the HydroBench bench under proportional control, co-simulated
with fmpy: bench.fmu (the plant) and controller.fmu (u1 = -u2 = Kp (y_ref - y)) exchange
values every 1 ms, the controller's sampling period.

    python tools/fmpy/simulate_bench.py [--fmu-dir target/fmu] [--out out/fmpy]
                                        [--controller fmu|python] [--kp 1169] [--mode 3]

`--controller python` closes the loop with the same law written in Python instead of
controller.fmu: the "external controller" use of bench.fmu. Writes <out>/bench_step.csv
(SI units) and, when matplotlib is installed, <out>/bench_step.png.
"""
import argparse
import csv
import tempfile
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

ROOT = Path(__file__).resolve().parents[2]
COLUMNS = ["time", "y_ref", "y", "v", "P1", "P2", "u1", "u2"]


def load(path, tmp):
    """Instantiate an FMU; returns it with its value references by name."""
    md = read_model_description(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path), tmp),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=path.stem)
    fmu.instantiate()
    return fmu, {v.name: v.valueReference for v in md.modelVariables}


def simulate(fmu_dir, controller="fmu", kp=1169.0, mode=3, step=0.010, t_step=0.01,
             stop=0.2, h=1e-3):
    with tempfile.TemporaryDirectory() as tmp:
        bench, b = load(Path(fmu_dir) / "bench.fmu", tmp + "/bench")
        ctl, c = load(Path(fmu_dir) / "controller.fmu", tmp + "/controller")
        bench.setInteger([b["mode"]], [mode])
        ctl.setReal([c["Kp"]], [kp])
        for fmu in (bench, ctl):
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
        rows = []
        for k in range(round(stop / h) + 1):
            t = k * h
            y_ref = step if t >= t_step - 1e-12 else 0.0
            y, v, p1, p2 = bench.getReal([b["y"], b["v"], b["P1"], b["P2"]])
            if controller == "fmu":
                ctl.setReal([c["y_ref"], c["y"], c["P1"], c["P2"]], [y_ref, y, p1, p2])
                u1, u2 = ctl.getReal([c["u1"], c["u2"]])
            else:  # the same law, (4.22), outside any FMU
                u1 = min(max(kp * (y_ref - y), -10.0), 10.0)
                u2 = -u1
            rows.append([t, y_ref, y, v, p1, p2, u1, u2])
            if k * h < stop - 1e-12:
                bench.setReal([b["u1"], b["u2"]], [u1, u2])
                bench.doStep(t, h)
                ctl.doStep(t, h)
        for fmu in (bench, ctl):
            fmu.terminate()
            fmu.freeInstance()
    return rows


def rise_time(rows, step=0.010, t_step=0.01, fraction=0.95):
    """Time from the step to the first sample at `fraction` of it."""
    return next((r[0] - t_step for r in rows if r[0] >= t_step and r[2] >= fraction * step), None)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmu-dir", default=ROOT / "target" / "fmu", type=Path)
    ap.add_argument("--out", default=ROOT / "out" / "fmpy", type=Path)
    ap.add_argument("--controller", choices=["fmu", "python"], default="fmu")
    ap.add_argument("--kp", type=float, default=1169.0, help="V/m (section 4.4: 1169)")
    ap.add_argument("--mode", type=int, default=3, choices=[1, 2, 3])
    ap.add_argument("--stop-time", type=float, default=0.2)
    a = ap.parse_args(argv)
    rows = simulate(a.fmu_dir, a.controller, a.kp, a.mode, stop=a.stop_time)
    a.out.mkdir(parents=True, exist_ok=True)
    with open(a.out / "bench_step.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        w.writerows([repr(x) for x in r] for r in rows)
    t95 = rise_time(rows)
    print(f"{a.out / 'bench_step.csv'}: y = {rows[-1][2] * 1e3:.3f} mm at {rows[-1][0]:g} s, "
          f"95 % rise time {'-' if t95 is None else f'{t95 * 1e3:.0f} ms'}")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return 0
    t = [r[0] for r in rows]
    fig, (ax1, ax2) = plt.subplots(2, sharex=True)
    ax1.plot(t, [r[1] * 1e3 for r in rows], "--", t, [r[2] * 1e3 for r in rows])
    ax1.set_ylabel("y (mm)")
    ax2.plot(t, [r[4] / 1e5 for r in rows], t, [r[5] / 1e5 for r in rows])
    ax2.set_ylabel("P1, P2 (bar)")
    ax2.set_xlabel("t (s)")
    fig.savefig(a.out / "bench_step.png", dpi=120)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
