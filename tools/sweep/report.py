"""What a study leaves in DIR beside results.jsonl: results.csv (one row per point, SI),
sensitivity.csv (factors ranked per metric) and the plots (PNG).

Sensitivity is rank-based, so it needs no model of the response: for a numeric factor
the Spearman rank correlation between factor and metric (|rho|, sign kept beside it),
for a categorical one (a case, a control law given by name, a switch) the correlation
ratio eta (the share of the metric's spread explained by the category means, square
rooted). Both lie in [0, 1] and read alike: 0 = no monotone effect, 1 = the metric
follows the factor alone. Over a Monte Carlo they rank the factors of a coupled study;
over a grid they say the same of the levels tried.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

from .evaluate import METRICS

#: (scale, unit) for the plots; the CSV files stay SI.
DISPLAY = {
    "transient_max": (1e6, "um"), "transient_rms": (1e6, "um"), "transient_std": (1e6, "um"),
    "static_mean": (1e6, "um"), "static_std": (1e6, "um"), "static_max": (1e6, "um"),
    "peak_pressure": (1e-5, "bar"), "energy": (1.0, "J"),
}


def _cell(x: Any) -> str:
    if x is None:
        return ""
    if isinstance(x, float):
        return repr(x)
    return str(x)


def factor_columns(points: list[dict], factor_names: list[str]) -> list[str]:
    cols = ["case"] if any(p["case"] is not None for p in points) else []
    return cols + factor_names


def write_csv(path: Path, records: list[dict], factors: list[str], metrics: list[str]) -> None:
    """One row per point in the study's order: id, factors, status, metrics (SI), timing."""
    header = ["id", *factors, "status", *metrics, "wall_time", "worker", "error", "notes"]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for rec in records:
            values = {"case": rec.get("case"), **rec.get("values", {})}
            m = rec.get("metrics", {})
            w.writerow([rec["id"], *(_cell(values.get(k)) for k in factors), rec["status"],
                        *(_cell(m.get(k)) for k in metrics), _cell(rec.get("wall_time")),
                        rec.get("worker", ""), rec.get("error", ""), "; ".join(rec.get("notes", [])) ])


def average_ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 0..n-1, ties sharing their mean rank."""
    order = np.argsort(x, kind="stable")
    ranks = np.empty(len(x))
    sorted_x = x[order]
    start = 0
    for end in range(1, len(x) + 1):
        if end == len(x) or sorted_x[end] != sorted_x[start]:
            ranks[order[start:end]] = (start + end - 1) / 2
            start = end
    return ranks


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    rx, ry = average_ranks(x), average_ranks(y)
    sx, sy = rx.std(), ry.std()
    if sx == 0 or sy == 0:
        return math.nan
    return float(np.mean((rx - rx.mean()) * (ry - ry.mean())) / (sx * sy))


def correlation_ratio(groups: list[Any], y: np.ndarray) -> float:
    total = float(np.sum((y - y.mean()) ** 2))
    if total == 0:
        return math.nan
    between = 0.0
    for g in set(groups):
        sel = np.array([k == g for k in groups])
        between += sel.sum() * (y[sel].mean() - y.mean()) ** 2
    return math.sqrt(between / total)


def _numeric(values: list[Any]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def sensitivity(records: list[dict], factors: list[str], metrics: list[str]) -> list[dict]:
    """Rows {metric, factor, method, importance, rho, n}, most important first per metric."""
    ok = [r for r in records if r["status"] == "ok"]
    rows = []
    for metric in metrics:
        pairs = [({"case": r.get("case"), **r["values"]}, r["metrics"].get(metric)) for r in ok]
        pairs = [(v, m) for v, m in pairs if isinstance(m, (int, float)) and math.isfinite(m)]
        if len(pairs) < 3:
            continue
        y = np.array([m for _, m in pairs], dtype=float)
        found = []
        for factor in factors:
            xs = [v.get(factor) for v, _ in pairs]
            if len(set(map(repr, xs))) < 2:
                continue
            if _numeric(xs):
                rho = spearman(np.array(xs, dtype=float), y)
                found.append({"metric": metric, "factor": factor, "method": "spearman",
                              "importance": abs(rho), "rho": rho, "n": len(y)})
            else:
                eta = correlation_ratio([repr(x) for x in xs], y)
                found.append({"metric": metric, "factor": factor, "method": "eta",
                              "importance": eta, "rho": math.nan, "n": len(y)})
        found.sort(key=lambda r: -r["importance"] if math.isfinite(r["importance"]) else 1.0)
        rows.extend(found)
    return rows


def write_sensitivity(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["metric", "factor", "method", "importance", "rho", "n"])
        for r in rows:
            w.writerow([r["metric"], r["factor"], r["method"], _cell(r["importance"]), _cell(r["rho"]), r["n"]])


def _label(x: Any) -> str:
    return x if isinstance(x, str) else repr(x)


def _order(key: Any) -> list:
    """Sort key of a group: numbers by value, anything else by its text."""
    parts = key if isinstance(key, tuple) else (key,)
    return [(0, float(x), "") if _numeric([x]) else (1, 0.0, repr(x)) for x in parts]


def _metric_figure(plt, title: str, ok: list[dict], varied: list[str], grid_factors: set[str],
                   metric: str, not_ok: int):
    """The metric against each varied factor: one line per combination of the other
    factors when all are grid factors, else a scatter coloured by case."""
    scale, unit = DISPLAY.get(metric, (1.0, ""))
    rows = [({"case": r.get("case"), **r["values"]}, r["metrics"].get(metric)) for r in ok]
    rows = [(v, y * scale) for v, y in rows if isinstance(y, (int, float)) and math.isfinite(y)]
    shown = [f for f in varied if f != "case"] or varied
    if not rows or not shown:
        return None
    fig, axes = plt.subplots(1, len(shown), figsize=(4.4 * len(shown), 3.8), squeeze=False)
    for ax, factor in zip(axes[0], shown):
        xs_all = [v.get(factor) for v, _ in rows]
        numeric = _numeric(xs_all)
        cats = sorted({_label(x) for x in xs_all})
        position = (lambda x: x) if numeric else (lambda x: cats.index(_label(x)))
        others = [f for f in varied if f != factor]
        lines = factor in grid_factors and all(f in grid_factors for f in others)
        key = (lambda v: tuple(v.get(f) for f in others)) if lines else (lambda v: v.get("case"))
        groups: dict[Any, list] = {}
        for v, y in rows:
            groups.setdefault(key(v), []).append((position(v.get(factor)), y))
        for i, (g, pts) in enumerate(sorted(groups.items(), key=lambda kv: _order(kv[0]))):
            pts.sort(key=lambda p: p[0])
            label = ", ".join(f"{f}={_label(x)}" for f, x in zip(others, g)) if lines else g
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-" if lines else "o", ms=3.5, lw=1,
                    alpha=0.8, color=plt.cm.tab10(i % 10), label=label)
        if not numeric:
            ax.set_xticks(range(len(cats)), cats, rotation=30, ha="right", fontsize=7)
        ax.set_xlabel(factor)
        ax.set_ylabel(f"{metric} ({unit})" if unit else metric)
        ax.grid(alpha=0.3)
        if 1 < len(groups) <= 10 and any(label is not None for label in groups):
            ax.legend(fontsize=6)
    fig.suptitle(f"{title}: {metric}" + (f" ({not_ok} points not ok, left out)" if not_ok else ""), fontsize=10)
    fig.tight_layout()
    return fig


def plot(out: Path, title: str, records: list[dict], factors: list[str], metrics: list[str],
         grid_factors: set[str], rows: list[dict]) -> list[Path]:
    """metric_<name>.png (the metric against each factor) and sensitivity.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in records if r["status"] == "ok"]
    varied = [f for f in factors if len({repr({"case": r.get("case"), **r["values"]}.get(f)) for r in ok}) > 1]
    written = []
    for metric in metrics:
        fig = _metric_figure(plt, title, ok, varied, grid_factors, metric, len(records) - len(ok))
        if fig is None:
            continue
        path = out / f"metric_{metric}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    by_metric: dict[str, list[dict]] = {}
    for r in rows:
        by_metric.setdefault(r["metric"], []).append(r)
    if by_metric:
        fig, axes = plt.subplots(1, len(by_metric), figsize=(3.6 * len(by_metric), 0.5 + 0.45 * max(len(v) for v in by_metric.values()) + 1.2), squeeze=False)
        for ax, (metric, rs) in zip(axes[0], by_metric.items()):
            rs = [r for r in rs if math.isfinite(r["importance"])][::-1]
            ax.barh([r["factor"] for r in rs], [r["importance"] for r in rs],
                    color=["tab:orange" if r["method"] == "eta" else "tab:blue" for r in rs])
            ax.set_xlim(0, 1)
            ax.set_title(metric, fontsize=9)
            ax.tick_params(labelsize=7)
        fig.suptitle(f"{title}: sensitivity (|Spearman rho| blue, eta orange)", fontsize=10)
        fig.tight_layout()
        path = out / "sensitivity.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written


__all__ = ["METRICS", "write_csv", "sensitivity", "write_sensitivity", "plot", "factor_columns"]
