"""The points of a study: grid levels, random or Latin-hypercube draws, and cases.

Draws are made once for the study (seeded) and crossed with every grid level and case,
so that, say, each control law meets the same payloads and bulk moduli (common random
numbers: differences between laws are not sampling noise).
"""
from __future__ import annotations

import itertools
import math
from statistics import NormalDist
from typing import Any

import numpy as np

from .study import Factor, Study


def unit_draws(n: int, dims: int, method: str, seed: int) -> np.ndarray:
    """n points in the unit cube [0, 1)^dims: independent uniforms, or a Latin hypercube
    (each dimension cut into n equal strata, one point in each, strata paired at random)."""
    rng = np.random.default_rng(seed)
    if method == "random":
        return rng.random((n, dims))
    if method == "lhs":
        strata = np.stack([rng.permutation(n) for _ in range(dims)], axis=1)
        return (strata + rng.random((n, dims))) / n
    raise ValueError(f"unknown sampling {method!r}")


def from_unit(factor: Factor, u: float) -> Any:
    """The factor's value at quantile u (inverse transform of its distribution)."""
    a = factor.args
    if factor.distribution == "uniform":
        return a["min"] + u * (a["max"] - a["min"])
    if factor.distribution == "loguniform":
        return math.exp(math.log(a["min"]) + u * (math.log(a["max"]) - math.log(a["min"])))
    if factor.distribution == "normal":
        dist = NormalDist(a["mean"], a["std"])
        lo = dist.cdf(a["min"]) if "min" in a else 0.0
        hi = dist.cdf(a["max"]) if "max" in a else 1.0
        # truncated to [min, max]; keep away from the open ends where inv_cdf is infinite
        q = min(max(lo + u * (hi - lo), 1e-12), 1.0 - 1e-12)
        return dist.inv_cdf(q)
    if factor.distribution == "choice":
        values = a["values"]
        return values[min(int(u * len(values)), len(values) - 1)]
    raise ValueError(f"{factor.name}: no distribution")


def design(study: Study) -> list[dict[str, Any]]:
    """Every point as {"case": label or None, "values": {FMU name: study value}}, in a
    fixed order: cases, then grid levels (last factor fastest), then draws."""
    grid = [f for f in study.factors if f.values is not None]
    drawn = [f for f in study.factors if f.distribution]
    if drawn:
        u = unit_draws(study.samples, len(drawn), study.sampling, study.seed)
        draws = [
            {f.name: from_unit(f, float(u[i, j])) for j, f in enumerate(drawn)}
            for i in range(study.samples)
        ]
    else:
        draws = [{}]
    cases = study.cases or [None]
    points = []
    for case in cases:
        for levels in itertools.product(*(f.values for f in grid)):
            for draw in draws:
                values = dict(zip((f.name for f in grid), levels))
                values.update(draw)
                points.append({"case": case.label if case else None, "values": values})
    return points
