"""tools/blind_tally.py counts issue 14's figures by its stated rules: the latest set's
case wins, a newer set that did not judge a case keeps the older judgement, a .jsonl
re-run replaces what was named, and a hidden effect that is on in the known model counts
as named by its recalibration when nothing was added."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TALLY = ROOT / "tools" / "blind_tally.py"

TOLD = {"ln_bayes": 10.0, "ln_bayes_sd": 1.0}
UNTOLD = {"ln_bayes": 4.0, "ln_bayes_sd": 1.0}  # 4 - 1.28 < 3


def case(hidden, named, rivalry=None, seed=1, **more):
    return dict(hidden=hidden, experiment="steps", seed=seed, named=named, simulator="rust",
                identifiable=True if rivalry else None, rivalry=rivalry, **more)


def run(tmp: Path, *extra: str) -> str:
    out = subprocess.run([sys.executable, str(TALLY), str(tmp), *extra], check=True,
                         capture_output=True, text=True)
    return out.stdout


def test_the_rules(tmp_path: Path):
    old = [case(["dry_friction"], [], TOLD), case(["payload"], ["manifold_volume"], TOLD),
           case(["viscous_friction"], [], TOLD), case(["sensor_delay"], ["sensor_delay"], UNTOLD),
           case([], [])]
    (tmp_path / "set.json").write_text(json.dumps(old))
    # a newer set re-ran the dry friction (now named) without judging it again
    newer = [dict(case(["dry_friction"], ["dry_friction"]), identifiable=None, rivalry=None)]
    (tmp_path / "rerun_session40.json").write_text(json.dumps(newer))
    # a re-run named nothing but recalibrated the viscous term: the effect is named by it
    row = {"case": "rust_steps_1_viscous_friction", "named": [],
           "recal": ["actuator.viscous_friction", "sv1.rated_flow"]}
    (tmp_path / "price_session41.jsonl").write_text(json.dumps(row) + "\n")
    text = run(tmp_path)
    assert "nothing hidden, nothing added: 1 of 1 (100 %)" in text
    # told: dry friction (kept judgement), payload, viscous; the delay is not told
    assert "told 3 of 4 judged; named first 2 of 3 (67 %)" in text
    assert "told miss: rust steps seed 1 payload" in text
    assert "dry_friction" not in [l for l in text.splitlines() if "told miss" in l][0]


def test_on_record_judgements_are_merged_by_case(tmp_path: Path):
    (tmp_path / "set.json").write_text(json.dumps([case(["payload"], ["payload"], TOLD)]))
    (tmp_path / "elsewhere").mkdir()
    judged = tmp_path / "elsewhere" / "judged.json"
    judged.write_text(json.dumps([case(["payload"], ["payload"], TOLD, rivalry_on_record=UNTOLD)]))
    text = run(tmp_path, "--on-record", str(judged))
    assert "The bench's own record (blind/on_record.rs): told 0 of 1 judged" in text


def test_a_rerun_named_in_step_order_settles_a_lost_order(tmp_path: Path):
    (tmp_path / "set.json").write_text(json.dumps([case(["viscous_friction"], [], TOLD)]))
    # an effect added beside the hidden viscous term's recalibration: which came first is
    # lost, so the case is listed and counted as the added effect
    lost = {"case": "rust_steps_1_viscous_friction", "named": ["entrained_air"],
            "recal": ["actuator.viscous_friction"]}
    (tmp_path / "price_session40.jsonl").write_text(json.dumps(lost) + "\n")
    text = run(tmp_path)
    assert "named first 0 of 1" in text and "order lost" in text
    # a later re-run names in step order, the recalibration in its place: the order is known
    rerun = {"case": "rust_steps_1_viscous_friction", "named_in_order": True,
             "named": ["viscous_friction", "entrained_air"],
             "recalibrated": ["actuator.viscous_friction"]}
    (tmp_path / "reruns_session41.jsonl").write_text(json.dumps(rerun) + "\n")
    text = run(tmp_path)
    assert "named first 1 of 1 (100 %)" in text and "order lost" not in text


def test_a_set_re_run_whole_later_wins_over_an_older_re_run_row(tmp_path: Path):
    (tmp_path / "set_session38.json").write_text(json.dumps([case(["manifold_volume"], [], TOLD)]))
    row = {"case": "rust_steps_1_manifold_volume", "named": ["manifold_losses"], "recal": []}
    (tmp_path / "warm_start_session39.jsonl").write_text(json.dumps(row) + "\n")
    assert "named first 0 of 1" in run(tmp_path)
    # the whole set run again in session 43 names the volume: its file is the newer
    again = [case(["manifold_volume"], ["manifold_volume"], TOLD)]
    (tmp_path / "set_session43.json").write_text(json.dumps(again))
    assert "named first 1 of 1 (100 %)" in run(tmp_path)


def test_a_case_made_under_the_drawn_lag_keeps_no_judgement_of_the_weak_one(tmp_path: Path):
    lag = {"sensors.pressure_lag": 4.0e-4, "sensors.lvdt_lag": 0.0}
    none = {"sensors.pressure_lag": 0.0, "sensors.lvdt_lag": 0.0}
    old = [case(["payload"], ["manifold_volume"], TOLD, form=lag),
           case(["dry_friction"], ["viscous_friction"], TOLD, form=none)]
    (tmp_path / "set_session40.json").write_text(json.dumps(old))
    text = run(tmp_path)
    assert "weak lag: 1 of the 2 Rust cases" in text
    assert "told 2 of 2 judged" in text
    # both run again after the lag fix, neither judged: the lagged case's record changed and
    # it keeps no judgement; the case without a lag keeps its own
    again = [dict(case(["payload"], ["payload"], form=lag), identifiable=None),
             dict(case(["dry_friction"], ["dry_friction"], form=none), identifiable=None)]
    (tmp_path / "set_session64.json").write_text(json.dumps(again))
    (tmp_path / "on_record").mkdir()
    judged = tmp_path / "on_record" / "told_session41.json"
    judged.write_text(json.dumps([case(["payload"], ["payload"], TOLD, form=lag,
                                       rivalry_on_record=TOLD)]))
    text = run(tmp_path, "--on-record", str(judged))
    assert "weak lag: 0 of the 2 Rust cases" in text
    assert "Transplanted signature (blind/rivals.rs): told 1 of 1 judged; named first 1 of 1" in text
    assert "own record" not in text
