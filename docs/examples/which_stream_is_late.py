#!/usr/bin/env python3
"""Which stream is late? The nav2 TurtleBot bag, from Python.

    PYTHONPATH=build/python python3 docs/examples/which_stream_is_late.py \
        ../shared/data/bags/nav2_turtlebot.mcap which_stream_is_late.png

1. driftlab.diagnose names the late stream, as `driftlab diagnose` does: the streams on a clock of their own (here
   Gazebo's simulation time) are judged against the fastest deliveries on that clock (peer_delay_s).
2. driftlab.open(...).read(channel) gives each stream's stamps and arrivals as NumPy arrays [us]; the plot shows
   every message's delay: its arrival minus its stamp, less the fastest deliveries of all the streams on the clock
   around it (the simulation runs slower than real time, so arrival minus stamp alone drifts). Streams stamped ahead
   of their peers (post-dated, as /tf's map -> odom from AMCL) are named and left out of the plot.
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

    # Every message's delay, from the stamps and arrivals themselves. A stream stamped ahead of its peers (here /tf,
    # whose map -> odom AMCL post-dates by its transform_tolerance) is left out: its stamps are not its delay.
    ahead = [c["name"] for c in timed if (c["peer_delay_s"] or 0) < 0]
    if ahead:
        print("stamped ahead of their peers (post-dated), not plotted:", ", ".join(ahead))
    log = driftlab.open(bag)
    start = d["start_utime"]
    series = {}
    for c in timed:
        if c["name"] in ahead:
            continue
        data = log.read(c["name"])
        stamp, arrival = data["stamp"], data["arrival"]
        if stamp is None:
            continue
        keep = stamp > 0
        series[c["name"]] = ((arrival[keep] - start) * 1e-6, (arrival[keep] - stamp[keep]) * 1e-3)  # [s], [ms]
    # The fastest deliveries on the clock: the smallest arrival-minus-stamp of any stream in each 5 s, and a line
    # through them (the simulation's clock runs at a steady rate against the recorder's).
    t_all = np.concatenate([t for t, _ in series.values()])
    raw_all = np.concatenate([r for _, r in series.values()])
    bins = (t_all // 5.0).astype(int)
    fastest_t, fastest = [], []
    for b in np.unique(bins):
        k = np.flatnonzero(bins == b)[np.argmin(raw_all[bins == b])]
        fastest_t.append(t_all[k])
        fastest.append(raw_all[k])
    line = np.polyfit(fastest_t, fastest, 1)
    floor = np.min(np.array(fastest) - np.polyval(line, fastest_t))

    fig, (ax, bars) = plt.subplots(2, 1, figsize=(9, 7), gridspec_kw={"height_ratios": [2, 1]})
    for name, (t, raw) in series.items():
        delay = raw - np.polyval(line, t) - floor
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
