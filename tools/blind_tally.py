#!/usr/bin/env python3
"""Issue 14's figures counted from the blind-study files, the same way every time.

The form-error study in docs/blind/form_error/ grew over sessions 22-41: whole sets
(`*.json`, lists of `blind.json` cases), later whole sets re-run with a newer binary
(`*_sessionNN.json`), and re-runs of a few cases (`*_sessionNN.jsonl`, one row each). Until
session 41 the headline figures were counted from them by hand. This script counts them
by rule:

1. Single hidden effects and nothing hidden; one record per case (joint records apart).
2. A case is the latest file's that holds it, files ordered by the session in their name
   (none: before session 33). A newer file that did not judge the case keeps the older
   judgement (`identifiable`, `rivalry`, `rivalry_on_record`).
3. The `.jsonl` re-runs then replace what the case named, in session order, unless a
   whole-set file of a later session holds the case (a set re-run whole is newer). Their rows
   list the added effects apart from the recalibrations, so a hidden effect that is on in
   the known model (internal leakage, viscous friction), which the study names by its
   recalibration, is taken as named first when nothing was added and its parameter was
   recalibrated; when something was added as well the order is lost, and the case is
   listed as ambiguous and counted as the effect added. Rows with `named_in_order`
   (session 41 on) name as the study does, the recalibration in its place.
4. Told = identifiable and ln B - 1.2816 sd >= 3 (`blind/rivals.rs`, `Rivalry::told`).
5. Until session 64 `hide` ran the Rust bench's sensor lags far weaker than drawn
   (docs/gap.md, session 63). A Rust case with a lag from a file of session 64 on is
   another record than the same case before: it takes no judgement made before session 64,
   neither from an older file nor from an --on-record file. The cases still from before
   are counted apart (`weak lag`).

Usage: tools/blind_tally.py [DIR] [--on-record FILE.json ...] [--cases OUT.json]

The judgements on the bench's own record (`hbench blind --summarise FILE --on-record`) are
kept apart, in DIR/on_record/ (session 41: told_session41.json), and merged by --on-record.
"""
import argparse
import glob
import json
import os
import re
from collections import defaultdict

# a hidden effect on in section 4.4's known model, and the parameter whose recalibration
# names it (gap/effects.rs)
ON = {"viscous_friction": "actuator.viscous_friction", "internal_leakage": "sv1.null_leakage"}
TOLD_QUANTILE = 1.2816
CLEAR_LN_BAYES = 3.0


def session(path):
    m = re.search(r"session(\d+)", path)
    return int(m.group(1)) if m else 0


# the first session whose `hide` runs the Rust bench's sensor lags as drawn
LAG_FIX_SESSION = 64


def weak_lag(c, made_in):
    """Whether case `c`, made in session `made_in`, is a Rust record whose sensor lag acted
    weaker than drawn."""
    form = c.get("form") or {}
    lag = form.get("sensors.pressure_lag", 0) > 0 or form.get("sensors.lvdt_lag", 0) > 0
    return c.get("simulator", "rust") == "rust" and lag and made_in < LAG_FIX_SESSION


def judged_on_another_record(c, made_in, judged_in):
    """A judgement of session `judged_in` does not hold for case `c` of session `made_in`
    when the lag fix lies between them."""
    return weak_lag(c, judged_in) and not weak_lag(c, made_in)


def key(sim, experiment, seed, hidden):
    return (sim, experiment, int(seed), hidden)


def load(directory):
    cases, ambiguous = {}, set()
    for f in sorted(glob.glob(os.path.join(directory, "*.json")), key=session):
        data = json.load(open(f))
        if not isinstance(data, list):
            continue
        for c in data:
            if len(c["hidden"]) > 1 or "+" in c["experiment"]:
                continue
            k = key(c.get("simulator", "rust"), c["experiment"], c["seed"],
                    c["hidden"][0] if c["hidden"] else "none")
            prev = cases.get(k)
            if prev and not judged_on_another_record(c, session(f), prev["_session"]):
                for field in ("identifiable", "rivalry", "rivalry_on_record"):
                    if c.get(field) is None and prev.get(field) is not None:
                        c[field] = prev[field]
            c["source"] = os.path.basename(f)
            c["_session"] = session(f)
            cases[k] = c
    for f in sorted(glob.glob(os.path.join(directory, "*.jsonl")), key=session):
        for line in open(f):
            r = json.loads(line)
            if "case" in r:
                sim, experiment, seed, hidden = r["case"].split("_", 3)
            else:
                sim, experiment, seed, hidden = r["simulator"], r["experiment"], r["seed"], r["hidden"]
            k = key(sim, experiment, seed, hidden)
            if k not in cases or session(f) < cases[k]["_session"]:
                continue
            named = list(r["named"])
            recalibrated = r.get("recal", r.get("recalibrated", []))
            par = ON.get(hidden)
            # the last row applied decides whether the order is lost; a row named in step
            # order (session 41 on) names as the study does, the recalibration in its place
            ambiguous.discard(k)
            if not r.get("named_in_order") and par and any(par in x for x in recalibrated):
                if named:
                    ambiguous.add(k)
                else:
                    named = [hidden]
            cases[k]["named"] = named
            cases[k]["source"] = os.path.basename(f)
            cases[k]["_session"] = session(f)
    return cases, ambiguous


def told(rivalry, case):
    if not rivalry or case.get("identifiable") is not True:
        return None
    return rivalry["ln_bayes"] - TOLD_QUANTILE * rivalry.get("ln_bayes_sd", 0.0) >= CLEAR_LN_BAYES


def first_right(c):
    first = c["named"][0] if c["named"] else None
    return first in c["hidden"] if c["hidden"] else first is None


def rate(hits, n):
    return f"{hits} of {n} ({100 * hits / n:.0f} %)" if n else "-"


def report(cases, judge, title):
    judged = [(k, c) for k, c in cases.items() if told(c.get(judge), c) is not None]
    if not judged:
        return
    t = [(k, c) for k, c in judged if told(c.get(judge), c)]
    hits = sum(first_right(c) for _, c in t)
    print(f"\n{title}: told {len(t)} of {len(judged)} judged; named first {rate(hits, len(t))}")
    per = defaultdict(lambda: [0, 0])
    for k, c in t:
        per[k[3]][0] += 1
        per[k[3]][1] += first_right(c)
    print("  per effect: " + ", ".join(f"{e} {h}/{n}" for e, (n, h) in sorted(per.items())))
    for k, c in sorted(t):
        if not first_right(c):
            print(f"  told miss: {k[0]} {k[1]} seed {k[2]} {k[3]}: named {c['named'][:2]} ({c['source']})")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("directory", nargs="?", default="docs/blind/form_error")
    ap.add_argument("--on-record", nargs="*", default=[],
                    help="blind.json files whose cases carry rivalry_on_record, merged in by case")
    ap.add_argument("--cases", help="write the merged cases as one blind.json")
    a = ap.parse_args()
    cases, ambiguous = load(a.directory)
    for f in a.on_record:
        for c in json.load(open(f)):
            k = key(c.get("simulator", "rust"), c["experiment"], c["seed"],
                    c["hidden"][0] if c["hidden"] else "none")
            if (k in cases and c.get("rivalry_on_record") is not None
                    and not judged_on_another_record(cases[k], cases[k]["_session"], session(f))):
                cases[k]["rivalry_on_record"] = c["rivalry_on_record"]
    single = [c for k, c in cases.items() if k[3] != "none"]
    none = [c for k, c in cases.items() if k[3] == "none"]
    print(f"cases: {len(cases)} ({len(single)} with one effect hidden, {len(none)} with nothing hidden)")
    print(f"nothing hidden, nothing added: {rate(sum(not c['named'] for c in none), len(none))}")
    print(f"named first over all single-effect cases: {rate(sum(first_right(c) for c in single), len(single))}")
    weak = [c for c in cases.values() if weak_lag(c, c["_session"])]
    rust = [c for c in cases.values() if c.get("simulator", "rust") == "rust"]
    print(f"weak lag: {len(weak)} of the {len(rust)} Rust cases were made before session "
          f"{LAG_FIX_SESSION} with a sensor lag, which then acted weaker than drawn")
    report(cases, "rivalry", "Transplanted signature (blind/rivals.rs)")
    report(cases, "rivalry_on_record", "The bench's own record (blind/on_record.rs)")
    if ambiguous:
        print("\norder lost (an effect added beside the hidden one's recalibration; counted as the added):")
        for k in sorted(ambiguous):
            print(f"  {k}")
    if a.cases:
        json.dump([{f: v for f, v in c.items() if f != "_session"} for _, c in sorted(cases.items())],
                  open(a.cases, "w"), indent=1)


if __name__ == "__main__":
    main()
