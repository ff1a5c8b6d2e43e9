#!/usr/bin/env python3
"""Which stream is late? The nav2 TurtleBot bag, from Python.

    PYTHONPATH=build/python python3 docs/examples/which_stream_is_late.py \
        ../shared/data/bags/nav2_turtlebot.mcap which_stream_is_late.png

1. driftlab.diagnose names the late stream, as `driftlab diagnose` does: the streams on a clock of their own (here
   Gazebo's simulation time) are judged against the fastest deliveries on that clock (peer_delay_s).
2. driftlab.open(...).read(channel) gives each stream's stamps and arrivals as NumPy arrays [us]; the plot shows
   every message's delay: its arrival minus its stamp, less the fastest deliveries of all the streams on the clock
   around it (the simulation runs slower than real time, so arrival minus stamp alone drifts).
"""
import sys

import matplotlib

matplotlib.use("Agg")  # headless: writes a PNG
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import driftlab  # noqa: E402


def main(bag, png):
    d = driftlab.diagnose(bag)
    timed = [c for c in d["channels"] if c["latency_s"] is not None]
    print("%-12s %8s %10s %10s %12s" % ("channel", "count", "lat p50", "lat p99", "after peers"))
    for c in timed:
        peer = c["peer_delay_s"]
        print("%-12s %8d %7.1f ms %7.1f ms %12s" % (c["name"], c["count"], c["latency_s"]["p50"] * 1e3,
                                                     c["latency_s"]["p99"] * 1e3,
                                                     "-" if peer is None else "%.1f ms" % (peer * 1e3)))
    # The late stream: the one arriving furthest after its peers on its clock, else the largest median latency.
    late = max(timed, key=lambda c: (c["peer_delay_s"] or 0, c["latency_s"]["p50"]))
    why = [r for r in late["reasons"] if "after the fastest" in r or "late" in r]
    print("\nthe late stream: %s%s" % (late["name"], (": " + why[0]) if why else ""))

    # Every message's delay, from the stamps and arrivals themselves.
    log = driftlab.open(bag)
    start = d["start_utime"]
    series = {}
    for c in timed:
        data = log.read(c["name"])
        stamp, arrival = data["stamp"], data["arrival"]
        if stamp is None:
            continue
        keep = stamp > 0
        series[c["name"]] = ((arrival[keep] - start) * 1e-6, (arrival[keep] - stamp[keep]) * 1e-3)  # [s], [ms]
    # The fastest deliveries on the clock: the smallest arrival-minus-stamp of any stream in each 5 s, as a line.
    t_all = np.concatenate([t for t, _ in series.values()])
    raw_all = np.concatenate([r for _, r in series.values()])
    edges = np.arange(0, t_all.max() + 5, 5.0)
    bins = np.digitize(t_all, edges)
    centres, floor = [], []
    for b in np.unique(bins):
        centres.append(t_all[bins == b].mean())
        floor.append(raw_all[bins == b].min())

    fig, (ax, bars) = plt.subplots(2, 1, figsize=(9, 7), gridspec_kw={"height_ratios": [2, 1]})
    for name, (t, raw) in series.items():
        delay = raw - np.interp(t, centres, floor)
        ax.plot(t, delay, ".", markersize=2, label="%s (median %.1f ms)" % (name, np.median(delay)))
    ax.set_yscale("symlog", linthresh=10)
    ax.set_xlabel("time since the bag's start [s]")
    ax.set_ylabel("delay after the fastest deliveries [ms]")
    ax.set_title("which stream is late? %s is" % late["name"])
    ax.legend(markerscale=5)
    names = [c["name"] for c in timed]
    x = np.arange(len(names))
    bars.bar(x - 0.2, [c["latency_s"]["p50"] * 1e3 for c in timed], 0.4, label="latency p50")
    bars.bar(x + 0.2, [c["latency_s"]["p99"] * 1e3 for c in timed], 0.4, label="latency p99")
    bars.set_xticks(x, names)
    bars.set_yscale("log")
    bars.set_ylabel("[ms] (driftlab diagnose)")
    bars.legend()
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    print("wrote", png)
    return late["name"]


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        sys.exit("usage: which_stream_is_late.py BAG [OUT.png]")
    main(sys.argv[1], sys.argv[2] if len(sys.argv) == 3 else "which_stream_is_late.png")
