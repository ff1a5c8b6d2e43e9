#!/usr/bin/env python3
"""Draws the plots of `driftlab sweep collect` / `driftlab batch collect` and writes their HTML page.

Usage: sweep_page.py RESULTS_JSON OUT_DIR

RESULTS_JSON is the merged table (docs/batch.md): columns, rows (one per point), the varied parameters and, for
batches, the rows ranked worst first. Sweeps: each metric against each varied parameter, one line per combination
of the other parameters, the line through the mean over seeds and a band from the smallest to the largest value.
Batches: the logs ranked, with their worst stream. Every plot is a PNG in OUT_DIR, embedded in OUT_DIR/index.html.
Exit codes: 0 done, 2 bad input, 3 matplotlib missing.
"""

import base64
import html
import json
import math
import os
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit(3)  # driftlab says so, or tries another python3

COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2", "#7f7f7f"]
STYLE = {
    "figure.dpi": 100,
    "savefig.dpi": 110,
    "font.size": 9.5,
    "axes.titlesize": 11,
    "axes.titleweight": "bold",
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.grid": True,
    "grid.color": "#e6e6e6",
    "legend.frameon": False,
}
# Metrics plotted against the parameters, when the table has them: label, unit.
METRICS = {
    "ate_rmse": ("ATE (RMSE)", "m"),
    "rpe_rmse": ("RPE (RMSE, translation)", "m"),
    "drops": ("drops found", "messages"),
    "estimator.late_rejected": ("late measurements rejected", "messages"),
}
REPEATS = ("seed", "log")  # what the spread is taken over


def number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def slug(text):
    return "".join(c if c.isalnum() else "-" for c in text).strip("-")


def sweep_plots(data, out_dir):
    rows = [r for r in data["rows"] if r.get("status") == "done"]
    varied = [k for k in data["varied"] if k not in REPEATS]
    metrics = [m for m in METRICS if any(number(r.get(m)) for r in rows)]
    # Offsets found on a channel whose clock offset is varied are worth a plot of their own.
    for k in varied:
        if k.startswith("faults.") and k.endswith(".clock_offset_s"):
            m = "offset_s." + k.split(".")[1]
            if any(number(r.get(m)) for r in rows):
                metrics.append(m)
    plots = []
    for metric in metrics:
        label, unit = METRICS.get(metric, ("clock offset found on " + metric.split(".", 1)[-1], "s"))
        for param in varied or [None]:
            others = [k for k in varied if k != param]
            series = {}
            for r in rows:
                if not number(r.get(metric)):
                    continue
                key = tuple((k, r.get(k)) for k in others)
                series.setdefault(key, {}).setdefault(r.get(param) if param else "all", []).append(r[metric])
            if not series:
                continue
            fig, ax = plt.subplots(figsize=(6.4, 3.9))
            all_x = sorted({x for s in series.values() for x in s}, key=lambda v: (not number(v), v if number(v) else str(v)))
            numeric = all(number(x) for x in all_x)
            pos = {x: (x if numeric else i) for i, x in enumerate(all_x)}
            for i, (key, by_x) in enumerate(sorted(series.items(), key=lambda kv: str(kv[0]))):
                color = COLORS[i % len(COLORS)]
                xs = sorted(by_x, key=lambda v: pos[v])
                px = [pos[x] for x in xs]
                mean = [sum(by_x[x]) / len(by_x[x]) for x in xs]
                lo = [min(by_x[x]) for x in xs]
                hi = [max(by_x[x]) for x in xs]
                name = ", ".join(f"{k}={v}" for k, v in key) or "mean"
                ax.plot(px, mean, "-o", color=color, label=name, markersize=4)
                if any(len(by_x[x]) > 1 for x in xs):
                    ax.fill_between(px, lo, hi, color=color, alpha=0.15, linewidth=0)
                for x in xs:
                    ax.plot([pos[x]] * len(by_x[x]), by_x[x], ".", color=color, alpha=0.5, markersize=3)
            values = [v for by_x in series.values() for vs in by_x.values() for v in vs]
            if min(values) > 0 and max(values) / min(values) > 100:
                ax.set_yscale("log")  # curves orders of magnitude apart stay readable
            if not numeric:
                ax.set_xticks(list(pos.values()))
                ax.set_xticklabels([str(x) for x in all_x])
            ax.set_xlabel(param or "")
            ax.set_ylabel(f"{label} [{unit}]")
            repeats = sorted({k for k in data["varied"] if k in REPEATS})
            spread = f"; band: min..max over {', '.join(repeats)}" if repeats else ""
            ax.set_title(f"{label} against {param}" if param else label)
            if len(series) > 1 or spread:
                ax.legend(fontsize=8, title=("mean" + spread) if spread else None, title_fontsize=8)
            fig.tight_layout()
            name = f"{slug(metric)}-vs-{slug(param or 'all')}.png"
            fig.savefig(os.path.join(out_dir, name))
            plt.close(fig)
            plots.append((f"{label} against {param}" if param else label, name))
    return plots


def batch_plots(data, out_dir):
    ranked = [r for r in data.get("ranked", data["rows"]) if r.get("status") == "done"][:30]
    if not ranked:
        return []
    has_ate = any(number(r.get("ate_rmse")) for r in ranked)
    fig, ax = plt.subplots(figsize=(7.0, 0.32 * len(ranked) + 1.2))
    names = [os.path.basename(r.get("log", r["id"])) for r in ranked][::-1]
    if has_ate:
        values = [r.get("ate_rmse") or 0 for r in ranked][::-1]
        ax.barh(names, values, color=COLORS[0])
        ax.set_xlabel("ATE (RMSE) [m]")
        title = "logs by ATE"
    else:
        faults = [r.get("fault_streams", 0) for r in ranked][::-1]
        warns = [r.get("warn_streams", 0) for r in ranked][::-1]
        ax.barh(names, faults, color=COLORS[1], label="streams with faults")
        ax.barh(names, warns, left=faults, color=COLORS[4], label="streams with warnings")
        ax.set_xlabel("streams flagged by the diagnosis")
        ax.legend(fontsize=8)
        title = "logs, worst first"
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "ranked.png"))
    plt.close(fig)
    return [(title, "ranked.png")]


def cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def table_html(columns, rows, limit=1000):
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = []
    for r in rows[:limit]:
        cls = "" if r.get("status") == "done" else f' class="{html.escape(str(r.get("status")))}"'
        body.append(f"<tr{cls}>" + "".join(f"<td>{html.escape(cell(r.get(c)))}</td>" for c in columns) + "</tr>")
    more = f"<p>{len(rows) - limit} more rows in results.csv</p>" if len(rows) > limit else ""
    return f"<table><tr>{head}</tr>{''.join(body)}</table>{more}"


def main(argv):
    if len(argv) != 3:
        print("usage: sweep_page.py RESULTS_JSON OUT_DIR", file=sys.stderr)
        return 2
    with open(argv[1], encoding="utf-8") as f:
        data = json.load(f)
    out_dir = argv[2]
    plt.rcParams.update(STYLE)
    rows = data["rows"]
    counts = {}
    for r in rows:
        counts[r.get("status")] = counts.get(r.get("status"), 0) + 1
    is_batch = "ranked" in data
    plots = batch_plots(data, out_dir) if is_batch else sweep_plots(data, out_dir)
    parts = [f"<h1>{html.escape(data['name'])}</h1>",
             "<p>" + ", ".join(f"{n} {html.escape(str(s))}" for s, n in sorted(counts.items(), key=str)) +
             f" of {len(rows)} {'logs' if is_batch else 'points'}; stages: {html.escape(', '.join(data['stages']))}; "
             "the whole table: <a href=\"results.csv\">results.csv</a>, <a href=\"results.json\">results.json</a></p>"]
    for title, name in plots:
        with open(os.path.join(out_dir, name), "rb") as f:
            b64 = base64.b64encode(f.read()).decode()
        parts.append(f"<figure><img src=\"data:image/png;base64,{b64}\" alt=\"{html.escape(title)}\">"
                     f"<figcaption>{html.escape(title)} ({html.escape(name)})</figcaption></figure>")
    if is_batch:
        cols = ["log", "status", "worst_stream", "worst_verdict", "worst_reason", "fault_streams", "warn_streams", "drops"]
        if any("ate_rmse" in r for r in rows):
            cols += ["ate_rmse", "rpe_rmse"]
        cols = [c for c in cols if any(c in r for r in data["ranked"])]
        parts.append("<h2>Logs, worst first</h2>" + table_html(cols, data["ranked"]))
    else:
        cols = [c for c in data["columns"] if not c.startswith("seconds.") or c == "seconds.total"]
        parts.append("<h2>Points</h2>" + table_html(cols, rows))
    page = ("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>" + html.escape(data["name"]) +
            "</title><style>body{font-family:sans-serif;margin:2em;max-width:1100px}"
            "table{border-collapse:collapse;font-size:12px}td,th{border:1px solid #ddd;padding:2px 6px}"
            "tr.failed{background:#fdd}tr.pending,tr.running{color:#888}figure{margin:1em 0}"
            "img{max-width:100%}</style></head><body>" + "\n".join(parts) + "</body></html>\n")
    tmp = os.path.join(out_dir, "index.html.partial")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(page)
    os.replace(tmp, os.path.join(out_dir, "index.html"))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
