#!/usr/bin/env python3
"""Draws the plots of `driftlab report` and writes its HTML page.

Usage: report_page.py REPORT_JSON OUT_DIR

REPORT_JSON is what `driftlab report` gathered from the logs (docs/report.md lists its fields). Every plot is
written to OUT_DIR as a PNG and embedded in OUT_DIR/index.html, so the page opens offline on its own. The time
plots are also drawn zoomable with dygraphs, read from Debian's libjs-dygraphs ($DRIFTLAB_DYGRAPHS_DIR, default
/usr/share/javascript/dygraphs) and inlined into the page; without it the page keeps the PNGs and says so.
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
    import numpy

    matplotlib.use("Agg")
    import matplotlib.lines
    import matplotlib.patches
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit(3)  # driftlab report says so, or tries another python3

DYGRAPHS_DIR = os.environ.get("DRIFTLAB_DYGRAPHS_DIR") or "/usr/share/javascript/dygraphs"
CHART_POINTS = 2000  # per series in an interactive chart: min and max of each bucket, so no spike is lost
LOG_SPREAD = 20  # a time plot's y axis is logarithmic when one curve's median is this many times another's
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
    "grid.linewidth": 0.8,
    "legend.frameon": False,
}


def ms(seconds):
    return seconds * 1e3


def quantile(values, q):
    """numpy's default quantile (linear between order statistics), the one definition core/quantile.h also uses."""
    if len(values) == 0:
        return 0.0
    return float(numpy.quantile(values, q))


class Page:
    """The plots drawn so far, in page order: (file, title, caption)."""

    def __init__(self, out_dir):
        self.out_dir = out_dir
        self.figures = []
        self.charts = {}  # figure file -> (the interactive charts drawn above it (see chart()), they replace it)
        self.notes = []  # what was left out of the plots, and why

    def save(self, fig, name, title, caption, charts=None, replaces=False):
        """charts: interactive charts drawn above the PNG; replaces: they show all the PNG shows, which then folds
        away under them."""
        # Written beside and renamed: a full disk never leaves a cut PNG over the one a user has.
        path = os.path.join(self.out_dir, name)
        try:
            fig.savefig(path + ".partial", format="png", bbox_inches="tight", facecolor="white")
            os.replace(path + ".partial", path)
        finally:
            plt.close(fig)
            if os.path.exists(path + ".partial"):
                os.remove(path + ".partial")
        self.figures.append((name, title, caption))
        if charts:
            self.charts[name] = (charts, replaces)


def decimate(x, y, points=CHART_POINTS):
    """At most about `points` of (x, y), keeping each bucket's lowest and highest y: a spike survives."""
    x, y = numpy.asarray(x, dtype=float), numpy.asarray(y, dtype=float)
    if len(x) <= points:
        return x, y
    keep = set()
    for bucket in numpy.array_split(numpy.arange(len(x)), points // 2):
        keep.add(int(bucket[numpy.argmin(y[bucket])]))
        keep.add(int(bucket[numpy.argmax(y[bucket])]))
    idx = numpy.asarray(sorted(keep))
    return x[idx], y[idx]


def spread(series):
    """How many times the largest median of |y| is the smallest (positive) one."""
    medians = [float(numpy.median(numpy.abs(y))) for y in series if len(y)]
    medians = [m for m in medians if m > 0]
    return max(medians) / min(medians) if len(medians) > 1 else 1.0


def chart(labels, columns, ylabel, height=320, log=False, shade=(), title=""):
    """An interactive chart: columns is [(x, y)] per label (x in seconds from the log's start), merged into dygraphs'
    one table of rows [x, y1, y2...] (null where a series has no point)."""
    rows = {}
    for i, (x, y) in enumerate(columns):
        for a, b in zip(*decimate(x, y)):
            row = rows.setdefault(round(float(a), 4), [None] * len(columns))
            row[i] = round(float(b), 5)
    data = [[x] + rows[x] for x in sorted(rows)]
    return {"labels": ["time [s]"] + list(labels), "data": data, "ylabel": ylabel, "height": height, "log": log,
            "shade": [[round(a, 4), round(b, 4)] for a, b in shade], "title": title}


def own_clock(data, e):
    """An estimate's times, in seconds from the log's start; one stamped on a clock of another epoch (simulation time
    in a bag of dates) from its own first stamp, never as a 1e9-second offset."""
    t = e["t"]
    duration = max([l["duration_s"] for l in data.get("logs", [])] + [1.0])
    if t and (t[0] < -10 * duration - 60 or t[0] > 10 * duration + 60):
        return [v - t[0] for v in t], True
    return t, False


def plot_trajectories(page, data):
    ref = data.get("reference")
    others = [r for r in data.get("other_references", []) if r["x"]]
    estimates = [e for e in data["estimates"] if e["x"]]
    apart = [e for e in data.get("apart", []) if e["x"]]
    if not ref and not estimates and not apart:
        return
    # Poses of another body (an arm's end effector beside its base's ground truth) are no estimate of the
    # reference: drawn apart, on axes of their own, never overlaid unaligned.
    fig, axes = plt.subplots(1, 2 if apart else 1, figsize=(13, 6.5) if apart else (8.5, 7), squeeze=False)
    ax = axes[0][0]
    if ref:
        ax.plot(ref["x"], ref["y"], color="black", lw=2.2, alpha=0.85, label=f"{ref['label']} (reference)")
        ax.plot(ref["x"][0], ref["y"][0], "o", color="black", ms=7)
    for r in others:  # a run flown again: its own truth, dashed
        ax.plot(r["x"], r["y"], color="#616161", lw=1.8, ls="--", alpha=0.85,
                label=f"{r['label']} (reference, flown again)")
    for i, e in enumerate(estimates):
        label = e["label"]
        if "ate_rmse" in e:
            label += f"  (ATE {e['ate_rmse']:.3f} m"
            label += f" against {e['reference']})" if e.get("reference") else ")"
        ax.plot(e["x"], e["y"], color=COLORS[i % len(COLORS)], lw=1.2, alpha=0.9, label=label)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Trajectories in the plane")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=1, fontsize=9 if apart else None)
    if apart:
        bx = axes[0][1]
        for i, e in enumerate(apart):
            color = COLORS[(len(estimates) + i) % len(COLORS)]
            bx.plot(e["x"], e["y"], color=color, lw=1.2, alpha=0.9, label=f"{e['label']} ({e['body']})")
            bx.plot(e["x"][0], e["y"][0], "o", color=color, ms=6)
        bx.set_aspect("equal", adjustable="datalim")
        bx.set_xlabel("x [m]")
        bx.set_ylabel("y [m]")
        bx.set_title("Other bodies, apart (not estimates of the reference)")
        bx.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=1, fontsize=9)
    aligned = " Estimates are aligned to the reference in position and yaw." if ref else ""
    onto = sorted({e["aligned_to"] for e in estimates if e.get("aligned_to")})
    if onto:
        aligned = (f" Without a reference, the others are aligned onto {onto[0]} (the longest) in position and "
                   "yaw, as evo_traj --ref does: poses in different frames are never overlaid as they are.")
    if others:
        aligned += (" A run flown again is drawn with the others: its truth dashed, its estimate scored against that "
                    "truth.")
    if apart:
        bodies = ", ".join(f"{e['label']} ({e['body']})" for e in apart)
        aligned += (f" Right: {bodies}, of another body than the reference's ({apart[0]['not_of']}): drawn apart, "
                    "as logged, never overlaid on it.")
    page.save(fig, "trajectories.png", "Trajectories",
              "Every pose channel, seen from above; the dot marks the reference's start." + aligned)


def plot_error_timeline(page, data):
    estimates = [e for e in data["estimates"] if e.get("error")]
    rows = [s for s in data["streams"] if s["gaps"] or s["spikes"]]  # a stream with nothing to mark is no row
    if not estimates and not rows:
        page.notes.append("Error over time: no estimate has a reference to be scored against, and no stream dropped "
                          "messages or had a latency spike.")
        return
    log = len(estimates) > 1 and spread([e["error"] for e in estimates]) > LOG_SPREAD
    if estimates and rows:
        fig, (top, bottom) = plt.subplots(
            2, 1, figsize=(11, 4.6 + 0.32 * len(rows)), sharex=True,
            gridspec_kw={"height_ratios": [3.2, 0.45 * len(rows) + 0.6]})
    elif estimates:
        fig, top = plt.subplots(figsize=(11, 4.2))
        bottom = None
    else:
        fig, bottom = plt.subplots(figsize=(11, 1.6 + 0.32 * len(rows)))
        top = None
    shade = [(g[0], g[0] + max(g[1] - g[0], 0.02)) for s in rows for g in s["gaps"]]
    if top is not None:
        for i, e in enumerate(estimates):
            t, _ = own_clock(data, e)
            top.plot(t, e["error"], color=COLORS[i % len(COLORS)], lw=1.1,
                     label=f"{e['label']}  (RMS {e['ate_rmse']:.3f} m)")
        top.set_ylabel("position error [m]" + (", log scale" if log else ""))
        if log:
            top.set_yscale("log")
        else:
            top.set_ylim(bottom=0)
        top.set_title("Position error over time" + (", with what went wrong in the streams" if rows else ""))
        for start, end in shade:
            top.axvspan(start, end, color="#d62728", alpha=0.08, lw=0)
        top.set_xlabel("time since the start of the log [s]")
        # Below the axes, never over the curves.
        top.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14 if bottom is None else -0.04),
                   ncol=2 if len(estimates) > 3 else 1, fontsize=8.5)
        if bottom is not None:
            top.xaxis.label.set_visible(False)
    if bottom is not None:
        if top is None:
            bottom.set_title("Drops and latency spikes over time")
        # One row per stream: drops as red bars over their gap, latency spikes as orange ticks.
        for row, s in enumerate(rows):
            y = len(rows) - 1 - row
            gaps = [(g[0], max(g[1] - g[0], 0.02)) for g in s["gaps"]]
            if gaps:
                bottom.broken_barh(gaps, (y - 0.35, 0.7), facecolors="#d62728", alpha=0.85)
            if s["spikes"]:
                bottom.plot([p[0] for p in s["spikes"]], [y] * len(s["spikes"]), "|", color="#ff7f0e", ms=11,
                            mew=1.6)
        bottom.set_yticks(range(len(rows)))
        bottom.set_yticklabels([s["channel"] for s in reversed(rows)])
        bottom.set_ylim(-0.7, len(rows) - 0.3)
        bottom.set_xlabel("time since the start of the log [s]")
        bottom.set_xlim(left=0)
        bottom.grid(axis="y", visible=False)
    fig.tight_layout()
    if bottom is not None:  # below the figure, never over the rows
        handles = [matplotlib.patches.Patch(color="#d62728", label="dropped messages (gap)"),
                   matplotlib.lines.Line2D([], [], color="#ff7f0e", marker="|", ls="", ms=11, mew=1.6,
                                           label="latency spike")]
        fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2)
    charts = []
    if estimates:
        columns = [(own_clock(data, e)[0], e["error"]) for e in estimates]
        charts.append(chart([f"{e['label']} (RMS {e['ate_rmse']:.3f} m)" for e in estimates], columns,
                            "position error [m]" + (", log" if log else ""), log=log, shade=shade))
    caption = ("Each estimate's position error against the reference (aligned in position and yaw, as the "
               "trajectories)" + ("; log scale: one error is more than 20 times another's" if log else "")
               + ("; red bands are drops in any stream" if shade and estimates else "") + "." if estimates else "")
    if rows:
        caption += (" Below, per stream with anything to mark (the others had no drop and no spike): the gaps left "
                    "by dropped messages (red) and latency spikes (orange: above the median by more than 10 ms and "
                    "three times the p99's distance from it).")
    page.save(fig, "error_timeline.png", "Error over time" if estimates else "Drops and latency spikes over time",
              caption.strip(), charts, replaces=not rows)


def grid_of(n, width=11, row_height=2.3):
    cols = min(3, max(1, n))
    rows_n = math.ceil(n / cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(width, row_height * rows_n + 0.6), squeeze=False)
    flat = [a for row in axes for a in row]
    for a in flat[n:]:
        a.set_visible(False)
    return fig, flat


def save_grid(page, fig, suptitle, name, title, caption, charts=None):
    fig.suptitle(suptitle, fontweight="bold")
    # The title's own band, 0.4 inch at the top, so that a tall grid's first row does not run into it.
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / fig.get_figheight()))
    page.save(fig, name, title, caption, charts)


def plot_latency(page, data):
    streams = [s for s in data["streams"] if s["latency"]]
    if not streams:
        return
    # A stream whose every message has the same latency is one bar: said in a line, not drawn as a panel.
    constant = [s for s in streams if max(s["latency"]) - min(s["latency"]) < 1e-5]
    varying = [s for s in streams if s not in constant]
    said = ""
    if constant:
        said = (" Constant latency, not drawn: "
                + ", ".join(f"{s['channel']} {nozero(format(ms(s['latency'][0]), '.1f'))} ms" for s in constant)
                + ".")
    if not varying:
        page.notes.append("Latency: every stream's latency is constant (" + said.split(": ", 1)[1].rstrip(".")
                          + "); no histogram drawn.")
        return
    fig, axes = grid_of(len(varying))
    for ax, s in zip(axes, varying):
        lat = [ms(v) for v in s["latency"]]
        p50 = quantile(lat, 0.5)
        lo, hi = min(lat), max(lat)
        span = max(hi - lo, 1.0)  # a nearly constant latency still gets a visible bar, 1/60 ms wide at least
        edges = [lo - 0.02 * span + k * span * 1.04 / 60 for k in range(61)]
        ax.hist(lat, bins=edges, color="#1f77b4", alpha=0.85)
        ax.axvline(p50, color="black", lw=1, ls="--")
        threshold = ms(s.get("spike_threshold", 0))
        if "spike_threshold" in s and threshold <= hi:
            ax.axvline(threshold, color="#ff7f0e", lw=1.2)
        ax.set_yscale("log")
        ax.set_title(f"{s['channel']}  (median {p50:.1f} ms)", fontsize=9.5)
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.set_xlabel("arrival - stamp on its clock's mapping [ms]" if s.get("mapped_clock")
                      else "arrival - stamp [ms]")
    # Over time, zoomable: one chart per stream, each on its own y range (a stream 1,000 times later than another
    # never flattens it), their time axes zoomed together.
    charts = []
    for s in varying:
        lat = [ms(v) for v in s["latency"]]
        # Spikes a thousand times the median flatten the rest: a log axis then, when all but a few latencies (under
        # 1%, not shown on it) are positive.
        log = sum(v <= 0 for v in lat) < 0.01 * len(lat) and max(lat) > LOG_SPREAD * max(quantile(lat, 0.5), 1e-3)
        charts.append(chart([s["channel"]], [(s["arrival"][:len(lat)], lat)],
                            "latency [ms]" + (", log" if log else ""), height=220, log=log, title=s["channel"]))
    save_grid(page, fig, "Latency per stream", "latency.png", "Latency",
              "Arrival time minus header stamp per message (a scan's from its last beam, as the diagnosis "
              "measures it): a clock offset moves the whole histogram, transport jitter widens it. A stream "
              "stamped on a clock of another epoch (simulation time) is drawn as the diagnosis judges it: its "
              "stamps through that clock's mapping to arrival, against the fastest stream on it. Histograms (log "
              "counts): dashed the median, orange the spike threshold. Over time: each stream on its own scale (log "
              "where its spikes are more than 20 times its median and under 1% of its latencies, not shown there, "
              "are zero or less), drag to zoom them all, double-click to reset."
              + said, charts)


def plot_interarrival(page, data):
    streams = [s for s in data["streams"] if len(s["arrival"]) > 2]
    if not streams:
        return

    def steady(s):  # every interval its period: a flat line on the dashed one, said rather than drawn
        period = s.get("expected_period_s") or 0
        dt = numpy.diff(numpy.asarray(s["arrival"]))
        return period > 0 and bool(numpy.all(numpy.abs(dt - period) <= max(0.01 * period, 5e-5)))

    regular = [s for s in streams if steady(s)]
    few = [s for s in streams if s not in regular and len(s["arrival"]) < 10]
    streams = [s for s in streams if s not in regular and s not in few]
    said = ""
    if few:
        said += " Fewer than ten messages, not drawn: " + ", ".join(
            f"{s['channel']} ({len(s['arrival'])})" for s in few) + "."
    if regular:
        said += (" Every interval its period, not drawn: "
                + ", ".join(f"{s['channel']} {ms(s['expected_period_s']):g} ms" for s in regular) + ".")
    if not streams:
        page.notes.append("Inter-arrival times: no stream to draw." + said)
        return
    fig, axes = grid_of(len(streams))
    for ax, s in zip(axes, streams):
        t = s["arrival"]
        dt = [round(ms(b - a), 3) for a, b in zip(t, t[1:])]  # arrivals are whole microseconds
        ax.plot(t[1:], dt, ".", ms=2.5, color="#2ca02c", alpha=0.6, rasterized=True)
        period = ms(s.get("expected_period_s") or 0)
        if period:
            ax.axhline(period, color="black", lw=1, ls="--")
        ax.set_ylim(0, max(max(dt) * 1.08, 2.2 * period, 1.0))
        ax.set_title(s["channel"], fontsize=9.5)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("interval [ms]")
    save_grid(page, fig, "Inter-arrival time per stream", "interarrival.png", "Inter-arrival times",
              "Time between consecutive arrivals: drops show as steps of whole periods above the dashed expected "
              "period, bursts as clusters, reordering and duplicates as points near zero." + said)


def plot_skew(page, data):
    pairs = [p for p in (data.get("diagnosis") or {}).get("pairs", []) if p.get("curve")]
    if not pairs:
        return
    fig, ax = plt.subplots(figsize=(10, 4.8))
    for i, p in enumerate(pairs):
        lags = [ms(c[0]) for c in p["curve"]]
        corr = [c[1] for c in p["curve"]]
        color = COLORS[i % len(COLORS)]
        ax.plot(lags, corr, color=color, lw=1.4,
                label=f"{p['a']} -> {p['b']}: {ms(p['offset_s']):+.1f} ms (confidence {p['confidence']:.2f})")
        ax.axvline(ms(p["offset_s"]), color=color, lw=0.9, ls=":")
    ax.axvline(0, color="black", lw=0.8)
    ax.set_xlabel("lag: how much later b is stamped than a [ms]")
    ax.set_ylabel("correlation of yaw rates")
    ax.set_title("Skew between streams that see the same motion")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=1)
    page.save(fig, "skew.png", "Skew correlation curves",
              "Correlation of the yaw rate two streams observe, against the lag between them; the peak (dotted) is "
              "the skew. A sharp single peak is trustworthy; a flat or double-peaked curve is not.")


FLIGHT_KINDS = [("dropout", "logger dropouts", "#d62728"), ("sensor_gap", "sensor gaps", "#ff7f0e"),
                ("rejection", "estimator rejections", "#9467bd"), ("timeout", "estimator timeouts", "#8c564b")]


def plot_flight_timeline(page, data):
    """A PX4 flight log's timeline: the logger's dropouts, the sensors' gaps and the estimator's rejections and
    timeouts on one time axis, a row per channel (per field for the estimator)."""
    flight = (data.get("diagnosis") or {}).get("flight_log")
    if not flight:
        return
    duration = max([l["duration_s"] for l in data.get("logs", [])] + [1.0])
    rows = []  # (label, color, [(start, width)])
    for kind, name, color in FLIGHT_KINDS:
        by_what = {}
        for e in flight.get("timeline", []):
            if e["kind"] == kind:
                by_what.setdefault(e["what"] if kind != "dropout" else name, []).append(e)
        for what in sorted(by_what, key=lambda w: -len(by_what[w]))[:10]:
            spans = [(e["start_s"], max(e["end_s"] - e["start_s"], duration * 0.002)) for e in by_what[what]]
            rows.append((what if kind != "dropout" else name, color, spans))
    if not rows:
        page.notes.append("Flight timeline: the flight log has no dropouts, sensor gaps or estimator rejections.")
        return
    fig, ax = plt.subplots(figsize=(11, 1.2 + 0.32 * max(len(rows), 1)))
    for i, (label, color, spans) in enumerate(rows):
        ax.broken_barh(spans, (i - 0.35, 0.7), facecolors=color)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels([r[0] for r in rows], fontsize=8)
    ax.set_ylim(-0.8, max(len(rows), 1) - 0.2)
    ax.invert_yaxis()
    ax.set_xlim(0, max([duration] + [start + width for _, _, spans in rows for start, width in spans]) * 1.01)
    ax.set_xlabel("time from the log's start [s]")
    handles = [matplotlib.patches.Patch(color=c, label=n) for k, n, c in FLIGHT_KINDS]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.35 if rows else -0.5), ncol=4,
              fontsize=8)
    d = flight.get("dropouts") or {}
    n = d.get("count", 0)
    title = (f"Flight timeline: {n} logger dropout{'' if n == 1 else 's'} ({ms(d.get('total_s', 0)):.0f} ms)"
             if rows else "Flight timeline: no dropouts, sensor gaps or estimator rejections")
    ax.set_title(title)
    page.save(fig, "flight_timeline.png", "Flight timeline",
              "The flight controller's own log on one time axis: the logger's dropouts (data missing from every "
              "topic), gaps in each sensor's samples (of 2.5 periods or more; labelled when at a dropout or shared "
              "by every sensor, i.e. the logger's or the whole system's, not the sensor's), and the spans where the "
              "estimator rejected a measurement (innovation test ratio over 1, or a rejection flag) or timed out.")


def fastest_window(t, commanded, width):
    """The [start, end] of `width` seconds where the commanded joints move the most (summed |change|)."""
    if len(t) < 2 or t[-1] - t[0] <= width:
        return (t[0], t[-1]) if t else (0, 1)
    moved = numpy.zeros(len(t))
    for q in commanded:
        moved[1:] += numpy.abs(numpy.diff(numpy.asarray(q)))
    cumulative = numpy.concatenate(([0.0], numpy.cumsum(moved)))
    tt = numpy.asarray(t)
    ends = numpy.searchsorted(tt, tt + width)
    gained = cumulative[numpy.minimum(ends, len(t))] - cumulative[numpy.arange(len(t))]
    start = int(numpy.argmax(gained[tt + width <= tt[-1]])) if (tt + width <= tt[-1]).any() else 0
    return tt[start], tt[start] + width


def plot_arms(page, data):
    for i, arm in enumerate(data.get("arms", [])):
        joints = arm["joints"]
        if not arm["t"] or not joints:
            continue
        delay = arm.get("delay_s")
        start, end = fastest_window(arm["t"], arm["commanded"], 3.0)
        t = numpy.asarray(arm["t"])
        shown = (t >= start) & (t <= end)
        panels = len(joints) + (1 if arm.get("curve") else 0)
        fig, axes = grid_of(panels, row_height=2.4)
        for ax, name, cmd, meas in zip(axes, joints, arm["commanded"], arm["measured"]):
            cmd, meas = numpy.asarray(cmd), numpy.asarray(meas)
            ax.plot(t[shown], cmd[shown], color="black", lw=1.3, ls="--", label="commanded")
            ax.plot(t[shown], meas[shown], color="#d62728", lw=1.4, label="measured")
            if delay is not None and abs(delay) >= 0.002:
                ax.plot(t[shown] - delay, meas[shown], color="#1f77b4", lw=1.0, ls=":",
                        label=f"measured {ms(delay):.1f} ms earlier")
            ax.set_xlim(start, end)
            ax.set_title(name, fontsize=9.5)
            ax.set_xlabel("time [s]")
            ax.set_ylabel("position [rad]")
        handles, labels = axes[0].get_legend_handles_labels()
        if arm.get("curve"):
            ax = axes[len(joints)]
            lags = [ms(c[0]) for c in arm["curve"]]
            ax.plot(lags, [c[1] for c in arm["curve"]], color="#2ca02c", lw=1.4)
            if delay is not None:
                ax.axvline(ms(delay), color="black", lw=1, ls="--")
            ax.set_ylim(max(-1.0, min(c[1] for c in arm["curve"])), 1.02)
            ax.set_xlabel("lag [ms]")
            ax.set_ylabel("agreement")
            ax.set_title("measured vs commanded, by lag", fontsize=9.5)
        if delay is None:
            said = "no delay measured (the joints do not follow the commanded motion clearly)"
        else:
            said = f"the joints follow {ms(delay):.1f} ms late (confidence {arm.get('confidence', 0):.2f})"
        fig.suptitle(f"{arm['command_channel']} -> {arm['state_channel']}: {said}", fontweight="bold")
        fig.tight_layout()
        fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=3, fontsize=8.5)
        page.save(fig, f"arm_{i}.png",
                  f"Arm: commanded and measured joint motion ({arm['command_channel']})",
                  "Each joint's commanded position (dashed: the plan of the last command stamped at or before each "
                  "time) and measured position (red: the joint states), over the 3 s in which the commanded joints "
                  "move the most; dotted: the measured motion moved earlier by the delay driftlab diagnose measures "
                  "from the motion. Last panel: how well the measured positions repeat the commanded ones at each "
                  "lag (1: the same motion); its peak is the delay.")


REASONS = ("stale", "future", "late", "outliers")


def plot_estimators(page, data):
    """Per estimator status channel: each input's share of rejected measurements over time, by reason."""
    for i, est in enumerate(data.get("estimators", [])):
        t = numpy.asarray(est["t"])
        # An input that rejected nothing is a flat line at zero: named in the caption, not drawn.
        rejected = [x for x in est["inputs"] if x["fused"] and any(max(x[r]) > 0 for r in REASONS)]
        clean = [x["name"] for x in est["inputs"] if x["fused"] and x not in rejected]
        said = f" Nothing rejected, not drawn: {', '.join(clean)}." if clean else ""
        inputs = rejected
        if len(t) < 2:
            continue
        if not inputs:
            page.notes.append(f"{est['label']}: the estimator rejected no measurement ({', '.join(clean)}).")
            continue
        fig, axes = grid_of(len(inputs), row_height=2.4)
        for ax, x in zip(axes, inputs):
            total = (numpy.asarray(x["fused"]) + numpy.asarray(x["stale"]) + numpy.asarray(x["future"])
                     + numpy.asarray(x["late"]) + numpy.asarray(x["outliers"])).astype(float)
            total[total == 0] = numpy.nan
            for reason, color in (("stale", "#9467bd"), ("future", "#d62728"), ("late", "#ff7f0e"),
                                  ("outliers", "#7f7f7f")):
                share = 100 * numpy.asarray(x[reason]) / total
                if numpy.nanmax(numpy.nan_to_num(share)) > 0:
                    ax.plot(t, share, color=color, lw=1.4, label=reason)
            ax.set_ylim(0, 100)
            ax.set_title(f"{x['name']}: {x['fused'][-1]:,} fused", fontsize=9.5)
            ax.set_xlabel("time [s]")
            ax.set_ylabel("rejected [% of received]")
        reasons = {}  # one legend for every panel, below them
        for ax in axes:
            for h, l in zip(*ax.get_legend_handles_labels()):
                reasons.setdefault(l, h)
        fig.suptitle(f"{est['label']}: what the estimator rejected", fontweight="bold")
        fig.tight_layout()
        fig.legend(list(reasons.values()), list(reasons), loc="upper center", bbox_to_anchor=(0.5, 0.0),
                   ncol=4, fontsize=8.5)
        page.save(fig, f"estimator_{i}.png",
                  f"Estimator: rejected measurements ({est['label']})",
                  "For each input of the estimator, the share of its measurements rejected so far, by reason, from "
                  "the estimator's own status messages: stale (stamped too long before the estimator's clock), "
                  "from the future (too far ahead of it: a source clock ahead), late (before the oldest state it "
                  "keeps) and outliers (failed the innovation test). A sensor on another clock shows as a share "
                  "that rises and stays." + said)


def plot_maps(page, data, out_dir):
    for i, m in enumerate(data["maps"]):
        image = plt.imread(os.path.join(out_dir, m["file"]))
        fig, ax = plt.subplots(figsize=(8, 8 * image.shape[0] / max(1, image.shape[1])))
        ax.imshow(image, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        ax.set_axis_off()
        ax.set_title(f"SLAM map: {m['label']}")
        page.save(fig, f"slam_map_{i}.png", f"SLAM map ({m['label']})",
                  "The occupancy grid the SLAM built (free white, occupied black, unknown grey; north up).")


# How each loop test is drawn: the closures the graph kept on top, the refused ones beneath them, faint.
LOOP_STYLES = [  # outcome, label, colour, line width, alpha
    ("low_overlap", "too little overlap", "#b0bec5", 0.6, 0.5),
    ("not_unique", "no unique match", "#ffb74d", 0.7, 0.6),
    ("ambiguous", "ambiguous (another place as good)", "#ba68c8", 0.8, 0.7),
    ("unconfirmed", "no second match confirmed it", "#8d6e63", 0.9, 0.8),
    ("refused_chi2", "refused: the graph contradicts it", "#e53935", 1.2, 0.9),
    ("accepted", "closure kept", "#2e7d32", 0.9, 0.9),
    ("undone", "closure undone at the end", "#b71c1c", 1.8, 1.0),
]


def plot_loops(page, data):
    """Each SLAM's loop tests on its trajectory: a segment from the keyframe to the old one it was matched with."""
    for i, lp in enumerate(data.get("loops", [])):
        fig, ax = plt.subplots(figsize=(8.5, 7))
        ax.plot(lp["path_x"], lp["path_y"], color="#90a4ae", linewidth=0.8, zorder=1, label="trajectory")
        undone = {(t["x"][0], t["y"][0], t["x"][1], t["y"][1]) for t in lp["tests"] if t["outcome"] == "undone"}
        counts = lp["counts"]
        for z, (outcome, label, color, width, alpha) in enumerate(LOOP_STYLES):
            tests = [t for t in lp["tests"] if t["outcome"] == outcome and
                     (outcome != "accepted" or (t["x"][0], t["y"][0], t["x"][1], t["y"][1]) not in undone)]
            if not tests:
                continue
            xs, ys = [], []
            for t in tests:
                xs += [t["x"][0], t["x"][1], None]
                ys += [t["y"][0], t["y"][1], None]
            n = counts.get(outcome, 0) - (counts.get("undone", 0) if outcome == "accepted" else 0)
            ax.plot(xs, ys, color=color, linewidth=width, alpha=alpha, zorder=2 + z, label=f"{label} ({n})")
            ax.plot([t["x"][0] for t in tests], [t["y"][0] for t in tests], "o", color=color, markersize=2,
                    alpha=alpha, zorder=2 + z)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"Loop closures: {lp['label']}")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.5, frameon=False)
        fig.tight_layout()
        tests = sum(v for k, v in counts.items() if k not in ("waiting", "undone"))
        page.save(fig, f"slam_loops_{i}.png", f"Loop closures ({lp['label']})",
                  f"Each of the SLAM's {tests} loop tests, drawn from the keyframe that tried it to the old "
                  f"keyframe it was matched against, on {lp['trajectory']} (the map frame, not aligned to anything). "
                  "Green: the "
                  "closures the graph kept; red: refused because the rest of the graph contradicts them, or "
                  "undone at the end (thick); the faint ones found too little overlap, no unique or an "
                  "ambiguous match, or no second match to confirm a large correction. A map folded by a wrong "
                  "closure shows it as a long green or red segment between places that differ. Each test's "
                  "figures are on its channel (driftlab.loop_closure_t, docs/slam.md).")


# --- the page -------------------------------------------------------------------------------------------------

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:0;color:#222;background:#fafafa}
header{background:#263238;color:#fff;padding:1.2em 2em}header h1{margin:0 0 .3em;font-size:1.5em}
header p{margin:0;color:#cfd8dc;font-size:.9em}main{padding:1em 2em;max-width:1250px}
section{background:#fff;border:1px solid #e0e0e0;border-radius:6px;padding:1em 1.4em;margin:1em 0}
h2{font-size:1.15em;margin:.2em 0 .6em}table{border-collapse:collapse;font-size:.88em}
th,td{padding:.3em .7em;border-bottom:1px solid #eee;text-align:right}th{background:#f5f5f5}
td:first-child,th:first-child{text-align:left}.fault{color:#b71c1c;font-weight:600}.warn{color:#e65100}
.ok{color:#2e7d32}figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}
figcaption{color:#555;font-size:.88em;max-width:900px}ul.problems li{margin:.2em 0}
.cards{display:flex;flex-wrap:wrap;gap:1em}.card{flex:1 1 200px;border-left:4px solid #546e7a;padding:.3em .8em}
.card b{display:block;font-size:1.25em}
.card.lead{flex:1 1 100%}.card.lead b{font-size:1.1em}.card.lead-fault{border-color:#c62828}
.card.lead-warn{border-color:#ef6c00}.card.lead-ok{border-color:#2e7d32}
.charts{display:grid;grid-template-columns:repeat(auto-fit,minmax(520px,1fr));gap:.6em 1.6em;margin:.6em 0}
.chart{width:100%}.chart-labels{font-size:.8em;color:#333;min-height:1.3em;margin:.2em 0 0 3em}
.chart-labels span{margin-right:.8em}.hint{color:#555;font-size:.85em;margin:.2em 0}
details summary{cursor:pointer;color:#37474f;font-size:.9em}
"""

CHECK = """
<script>
// Marks the page once every plot has decoded and drawn something (more than 1% of its pixels not white), for the
// headless-browser test and for anyone curious: body[data-plots], [data-plots-drawn], [data-plots-blank].
window.addEventListener('load', function () {
  var imgs = document.querySelectorAll('figure img');
  var drawn = 0, blank = 0;
  imgs.forEach(function (img) {
    if (!img.complete || img.naturalWidth === 0) return;
    var c = document.createElement('canvas');
    c.width = 200;
    c.height = Math.max(1, Math.round(200 * img.naturalHeight / img.naturalWidth));
    var g = c.getContext('2d');
    g.drawImage(img, 0, 0, c.width, c.height);
    var px = g.getImageData(0, 0, c.width, c.height).data, ink = 0;
    for (var i = 0; i < px.length; i += 4) if (px[i] + px[i + 1] + px[i + 2] < 600) ink++;
    if (ink > 0.01 * c.width * c.height) drawn++; else blank++;
  });
  document.body.setAttribute('data-plots', imgs.length);
  document.body.setAttribute('data-plots-drawn', drawn);
  document.body.setAttribute('data-plots-blank', blank);
});
</script>
"""


CHARTS = """
<script>
// Draws the zoomable charts with dygraphs (inlined above) and marks the page when done, for the headless-browser
// test: body[data-charts] charts to draw, [data-charts-drawn] drawn, [data-charts-ready] once all are,
// [data-js-errors] errors thrown. Charts of one group zoom together; double-click resets.
(function () {
  var specs = %(specs)s, colors = %(colors)s;
  var body = document.body, drawn = 0, errors = 0, groups = {}, syncing = false;
  body.setAttribute('data-charts', specs.length);
  body.setAttribute('data-js-errors', 0);
  window.addEventListener('error', function () { body.setAttribute('data-js-errors', ++errors); });
  specs.forEach(function (s) {
    try {
      var g = new Dygraph(document.getElementById(s.id), s.data, {
        labels: s.labels, ylabel: s.ylabel, xlabel: 'time since the start of the log [s]', title: s.title || null,
        titleHeight: s.title ? 22 : 0, logscale: s.log, height: s.height, connectSeparatedPoints: true,
        strokeWidth: 1.2, colors: s.labels.length > 2 ? colors : [colors[s.color %% colors.length]],
        labelsDiv: s.id + '-labels', legend: 'always', xRangePad: 4, includeZero: !s.log && s.zero,
        axes: {x: {valueFormatter: function (x) { return x.toFixed(3) + ' s'; }},
               y: {valueFormatter: function (y) { return y === null ? '-' : +y.toPrecision(5) + ''; },
                   axisLabelFormatter: function (y) { return +(+y).toPrecision(3) + ''; },
                   pixelsPerLabel: s.log ? 28 : 20, axisLabelWidth: 60}},
        underlayCallback: function (ctx, area, dg) {
          ctx.fillStyle = 'rgba(214,39,40,0.13)';
          s.shade.forEach(function (r) {
            var a = dg.toDomXCoord(r[0]), b = dg.toDomXCoord(r[1]);
            ctx.fillRect(a, area.y, Math.max(b - a, 1), area.h);
          });
        },
        drawCallback: function (dg, initial) {
          if (initial) {
            body.setAttribute('data-charts-drawn', ++drawn);
            if (drawn === specs.length) body.setAttribute('data-charts-ready', 1);
            return;
          }
          if (syncing) return;
          syncing = true;
          var range = dg.isZoomed('x') ? dg.xAxisRange() : null;
          (groups[s.group] || []).forEach(function (o) { if (o !== dg) o.updateOptions({dateWindow: range}); });
          syncing = false;
        }
      });
      (groups[s.group] = groups[s.group] || []).push(g);
    } catch (e) {
      body.setAttribute('data-js-errors', ++errors);
    }
  });
})();
</script>
"""


def dygraphs():
    """dygraphs' script and style from Debian's libjs-dygraphs, to inline into the page; None when absent."""
    try:
        with open(os.path.join(DYGRAPHS_DIR, "dygraph.min.js"), encoding="utf-8") as f:
            js = f.read()
        with open(os.path.join(DYGRAPHS_DIR, "dygraph.min.css"), encoding="utf-8") as f:
            css = f.read()
    except OSError:
        return None
    if "</script" in js.lower() or "</style" in css.lower():
        return None  # cannot be inlined as it is
    return js, css


def esc(x):
    return html.escape(str(x))


def nozero(text):
    """"-0.0" and "-0" read as a sign that is not there."""
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text


def fmt_ms(seconds):
    return "-" if seconds is None else nozero(f"{seconds * 1e3:.1f}") + " ms"


def summary_cards(data):
    summary = data.get("summary") or {}  # made by driftlab report (diagnosis_summary), as the demo prints it
    cards = []
    # The worst problem first, in diagnose's own words: its headline (the first of its problems) is the worst
    # stream's first reason, its cause (a clock 110 ms ahead, a command loop 120 ms late), then what follows from it.
    w = summary.get("worst_stream")
    if w and w["reasons"]:
        rest = w["reasons"][1:]
        follows = ("then: " + "; ".join(rest[:2]) + ("; ..." if len(rest) > 2 else "")) if rest else ""
        lead = (f"worst problem: {w['name']} ({w['verdict']}), as diagnose's headline says",
                f"{w['name']}: {w['reasons'][0]}", follows, w["verdict"])
    else:
        lead = ("worst problem", "none: no stream was flagged", "", "ok")
    ahead = [f"{name} {offset * 1e3:+.1f} ms" for name, offset in summary.get("clocks_ahead_s", {}).items()]
    cards.append(("clocks ahead", ", ".join(ahead[:3]) or "none by more than 1 ms",
                  "source clocks ahead of the recorder's"))
    drops = [f"{name} {n}" for name, n in summary.get("drops", {}).items()]
    cards.append(("dropped messages", ", ".join(drops[:3]) or "none", "from sequence gaps, or gaps in time"))
    # The card gives the table's ATE when `driftlab eval` scored the estimate (its alignment, said), else the one
    # plotted (aligned in position and yaw): a number on the page is the same number wherever it appears.
    evals = [e for e in data.get("evals", []) if "ate" in e["result"]]
    scored = set()
    for ev in evals:
        r = ev["result"]
        source = r["estimate"]["source"]
        plotted = [e for e in data.get("estimates", [])
                   if "ate_rmse" in e and (source == e["label"] or source.endswith("/" + e["label"]))]
        also = ""
        if plotted:
            scored.add(plotted[0]["label"])
            if r["alignment"]["type"] != "posyaw":
                also = f"; plotted aligned in position and yaw: {plotted[0]['ate_rmse']:.3f} m"
        cards.append((f"ATE {os.path.basename(source)}", f"{r['ate']['rmse']:.3f} m",
                      f"max {r['ate']['max']:.3f} m, {r['alignment']['type']} alignment, as in the table{also}"))
    for e in data.get("estimates", []):
        if "ate_rmse" in e and e["label"] not in scored:
            cards.append((f"ATE {e['label']}", f"{e['ate_rmse']:.3f} m",
                          f"max {e['ate_max']:.3f} m, aligned in position and yaw (posyaw), as plotted"))
    t, v, n, verdict = lead
    return (f"<div class='cards'><div class='card lead lead-{esc(verdict)}' id='headline'>{esc(t)}<b>{esc(v)}</b>"
            f"<small>{esc(n)}</small></div>" + "".join(
                f"<div class='card'>{esc(t)}<b>{esc(v)}</b><small>{esc(n)}</small></div>" for t, v, n in cards)
            + "</div>")


def channel_table(d):
    rows = []
    for c in d.get("channels", []):
        drops = c["drops"]["seq_gaps"] if c["drops"]["seq_gaps"] is not None else c["drops"]["missing_by_period"]
        lat = c.get("latency_s") or {}
        clock = c.get("clock") or {}
        rows.append(
            f"<tr><td>{esc(c['name'])}</td><td class='{esc(c['verdict'])}'>{esc(c['verdict'])}</td>"
            f"<td>{c['count']:,}</td><td>{c['rate_hz']:.2f}</td><td>{drops:,}</td><td>{c['duplicates']:,}</td>"
            f"<td>{c['out_of_order']['by_stamp']:,}</td><td>{fmt_ms(lat.get('p50'))}</td>"
            f"<td>{fmt_ms(lat.get('p99'))}</td><td>{fmt_ms(clock.get('offset_s'))}</td>"
            f"<td>{'-' if not clock else nozero(format(clock['drift_ppm'], '.0f')) + ' ppm'}</td></tr>")
    return ("<table><tr><th>channel</th><th>verdict</th><th>count</th><th>rate Hz</th><th>drops</th><th>dups</th>"
            "<th>reordered</th><th>latency p50</th><th>p99</th><th>clock offset</th><th>drift</th></tr>"
            + "".join(rows) + "</table>")


def problems_list(d):
    items = []
    for p in (d.get("flight_log") or {}).get("problems", []):
        items.append(f"<li class='warn'><b>flight log</b>: {esc(p)}</li>")
    for c in d.get("channels", []):
        for r in c["reasons"]:
            items.append(f"<li class='{esc(c['verdict'])}'><b>{esc(c['name'])}</b>: {esc(r)}</li>")
    for p in d.get("pairs", []):
        if abs(p["offset_s"]) >= 0.002 and p["confident"]:
            later = "later" if p["offset_s"] > 0 else "earlier"
            items.append(f"<li class='warn'><b>{esc(p['b'])}</b> is stamped {abs(p['offset_s']) * 1e3:.1f} ms "
                         f"{later} than {esc(p['a'])} for the same motion</li>")
    for t in (d.get("tf") or {}).get("problems", []):
        items.append(f"<li class='warn'><b>TF</b>: {esc(t)}</li>")
    return "<ul class='problems'>" + ("".join(items) or "<li class='ok'>no timing problems found</li>") + "</ul>"


def arm_table(evals):
    rows = []
    for e in evals:
        a = e["result"]["arm"]
        ee = a.get("ee")
        worst = max(a["joints"], key=lambda j: (j["error_rad"] or {}).get("rmse", 0))
        worst_rmse = math.degrees((worst["error_rad"] or {}).get("rmse", 0))
        if ee:
            pos, rot, osc = ee["position_m"], ee["rotation_deg"], ee["oscillation"]
            cells = (f"<td>{pos['rmse'] * 1e3:.2f}</td><td>{pos['max'] * 1e3:.2f}</td><td>{rot['rmse']:.3f}</td>"
                     f"<td>{rot['max']:.3f}</td><td>{osc['rms_m'] * 1e3:.3f} mm at {osc['peak_hz']:.1f} Hz</td>")
        else:
            cells = f"<td colspan='5'>{esc(a.get('ee_problem') or 'no end effector')}</td>"
        rows.append(f"<tr><td>{esc(e['file'])}</td><td>{esc(a['log'])}</td><td>{esc(a['reference'])}</td>"
                    f"<td>{esc(worst['name'])} {worst_rmse:.3f}</td>{cells}</tr>")
    return ("<section><h2>Arm tracking</h2><table><tr><th>file</th><th>log</th><th>reference</th>"
            "<th>worst joint rmse [deg]</th><th>EE rmse [mm]</th><th>EE max [mm]</th><th>EE rmse [deg]</th>"
            "<th>EE max [deg]</th><th>oscillation</th></tr>" + "".join(rows) + "</table></section>")


def eval_table(evals):
    if not evals:
        return ""
    arms = [e for e in evals if "arm" in e["result"]]
    evals = [e for e in evals if "ate" in e["result"]]
    if not evals:
        return arm_table(arms) if arms else ""
    rows = []
    for e in evals:
        r = e["result"]
        rpe = r["rpe"]["trans"]  # null when no pair of poses was delta apart
        rpe_rmse = f"{rpe['rmse']:.4f}" if rpe else "no pairs"
        rows.append(
            f"<tr><td>{esc(e['file'])}</td><td>{esc(r['estimate']['source'])}</td>"
            f"<td>{esc(r['alignment']['type'])}</td><td>{r['matched']:,}</td><td>{r['ate']['rmse']:.4f}</td>"
            f"<td>{r['ate']['max']:.4f}</td><td>{rpe_rmse}</td>"
            f"<td>{r['drift']['trans_pct']:.2f} %</td></tr>")
    return ("<section><h2>Trajectory evaluation</h2><table><tr><th>file</th><th>estimate</th><th>alignment</th>"
            "<th>matched</th><th>ATE rmse [m]</th><th>ATE max [m]</th><th>RPE rmse [m]</th><th>drift</th></tr>"
            + "".join(rows) + "</table></section>" + (arm_table(arms) if arms else ""))


def write_page(page, data, out_dir):
    d = data.get("diagnosis") or {}
    logs = "".join(f"<li>{esc(l['path'])}: {l['duration_s']:.1f} s"
                   + (f", {l['problems']} damaged spots" if l["problems"] else "") + "</li>" for l in data["logs"])
    library = dygraphs()
    figures, specs = [], []
    for name, title, caption in page.figures:
        with open(os.path.join(out_dir, name), "rb") as f:
            b64 = base64.b64encode(f.read()).decode("ascii")
        image = (f"<figure><a href='{esc(name)}'><img alt='{esc(title)}' src='data:image/png;base64,{b64}'></a>"
                 f"<figcaption>{esc(caption)}</figcaption></figure>")
        charts, replaces = page.charts.get(name, (None, False))
        zoom = ""
        if charts and library:
            divs = []
            for i, c in enumerate(charts):
                spec = dict(c, id=f"chart-{len(specs)}", group=name, color=i, zero=name == "error_timeline.png")
                specs.append(spec)
                divs.append(f"<div><div class='chart' id='{spec['id']}'></div>"
                            f"<div class='chart-labels' id='{spec['id']}-labels'></div></div>")
            zoom = ("<p class='hint'>Zoomable: drag across a chart to zoom in on that time, shift-drag to pan, "
                    "double-click to zoom back out.</p><div class='charts'>" + "".join(divs) + "</div>")
            if replaces:
                image = f"<details><summary>the same as a picture (PNG)</summary>{image}</details>"
        elif charts:
            zoom = ("<p class='hint'>The zoomable view of this plot needs libjs-dygraphs (<code>apt-get install "
                    "libjs-dygraphs</code>), not found in " + esc(DYGRAPHS_DIR) + "; this is its picture.</p>")
        figures.append(f"<section><h2>{esc(title)}</h2>{zoom}{image}</section>")
    if page.notes:
        figures.append("<section><h2>Not drawn</h2><ul>" + "".join(f"<li>{esc(n)}</li>" for n in page.notes)
                       + "</ul></section>")
    style, script = "", ""
    if library:
        style = library[1]
        script = ("<script>" + library[0] + "</script>"
                  + CHARTS % {"specs": json.dumps(specs, separators=(",", ":")).replace("</", "<\\/"),
                              "colors": json.dumps(COLORS)})
    unmatched = ""
    if data.get("unmatched"):
        unmatched = ("<p class='warn'>Left out of the trajectories: "
                     + esc(", ".join(data["unmatched"])) + "</p>")
    text = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(data['title'])}</title><style>{style}{CSS}</style></head>
<body><header><h1>{esc(data['title'])}</h1><p>made by driftlab report from:</p><ul>{logs}</ul></header><main>
<section><h2>Summary</h2>{summary_cards(data)}{unmatched}</section>
<section><h2>Streams</h2>{channel_table(d)}<h2 style="margin-top:1em">Problems</h2>{problems_list(d)}</section>
{eval_table(data.get('evals', []))}
{''.join(figures)}
</main>{CHECK}{script}</body></html>
"""
    path = os.path.join(out_dir, "index.html")
    try:
        with open(path + ".partial", "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(path + ".partial", path)
    finally:
        if os.path.exists(path + ".partial"):
            os.remove(path + ".partial")


def main(argv):
    if len(argv) != 3:
        sys.stderr.write(__doc__)
        return 2
    with open(argv[1], encoding="utf-8") as f:
        data = json.load(f)
    out_dir = argv[2]
    plt.rcParams.update(STYLE)
    page = Page(out_dir)
    plot_trajectories(page, data)
    plot_error_timeline(page, data)
    plot_latency(page, data)
    plot_interarrival(page, data)
    plot_skew(page, data)
    plot_flight_timeline(page, data)
    plot_arms(page, data)
    plot_estimators(page, data)
    plot_maps(page, data, out_dir)
    plot_loops(page, data)
    write_page(page, data, out_dir)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except OSError as e:  # a full disk, a file-size limit: one line naming the folder, exit 4 (driftlab exits 1)
        sys.stderr.write(f"{sys.argv[2] if len(sys.argv) > 2 else '.'}: cannot write the page: "
                         f"{e.strerror or e}\n")
        sys.exit(4)
