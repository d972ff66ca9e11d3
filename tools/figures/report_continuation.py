"""The bifurcations the continuation located along the paper's branch (run.kind: continue), beside
what the running method (run.kind: locate, rising_scan.h5) located on the same stretch, and the
windows where two stable orbits coexist (between a grazing corner and the fold beside it).
Markdown on stdout.

    python3 tools/figures/report_continuation.py continuation.h5 rising_scan.h5
"""
import sys

import h5py
import numpy as np

# Which of the running method's transition kinds corresponds to a continuation kind.
SAME = {"rising": "rising", "phase_change": "vanishing"}


def text(x):
    return x.decode() if isinstance(x, bytes) else str(x)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: report_continuation.py CONTINUATION.h5 RISING_SCAN.h5")
    with h5py.File(sys.argv[1], "r") as f:
        b = f["bifurcations"]
        names = [text(n) for n in b["kind"].attrs["names"]]
        notes = [text(n) for n in b["smooth"].attrs["notes"]]
        stops = [text(s) for s in f["scene/stop_name"][:]]
        rows = [(float(b["p"][i]), names[int(b["kind"][i])], int(b["stop"][i]), bool(b["smooth"][i]),
                 float(b["value"][i]), float(b["p_high"][i] - b["p_low"][i]), notes[i]) for i in range(b["p"].shape[0])]
        br = f["branch"]
        points, stable = br["p"].shape[0], int(np.sum(br["stable"][:]))
        bp, bstable, bsig = br["p"][:], br["stable"][:].astype(bool), br["signature"][:]
        maps = int(f["meta"].attrs["tangent_maps"])
        wall = float(f["meta"].attrs["wall_time"])
    with h5py.File(sys.argv[2], "r") as f:
        t = f["transitions"]
        tnames = [text(n) for n in t["kind"].attrs["names"]]
        running = [(tnames[int(t["kind"][i])], int(t["stop"][i]), float(t["parameter"][i]),
                    float(t["parameter_high"][i] - t["parameter_low"][i])) for i in range(t["kind"].shape[0])]
    rows.sort()
    print(f"Branch: {points} points ({stable} stable), {maps} tangent maps, {wall:.1f} s.\n")
    print("| kind | stop | located Ω | how | test function there | running method (locate) |")
    print("|---|---|---|---|---|---|")
    for p, kind, j, smooth, value, width, note in rows:
        stop = stops[j] if j >= 0 else "-"
        how = "solved" if smooth else f"bisected, bracket {width:.1e}"
        val = f"{value:.1e}" if smooth else "—"
        match = [r for r in running if SAME.get(kind) == r[0] and r[1] == j and abs(r[2] - p) < 1e-5]
        run = f"{match[0][2]:.9f} (bracket {match[0][3]:.1e})" if match else "not seen"
        print(f"| {kind} | {stop} | {p:.10f} | {how} | {val} | {run} |")
    # Coexistence: between a grazing corner and the fold next above it (nothing else between),
    # claimed only where the branch has stable points of two different event signatures inside.
    print()
    ordered = sorted(rows)
    for i, (p, kind, j, smooth, value, width, note) in enumerate(ordered):
        if kind != "grazing" or "corner" not in note or i + 1 >= len(ordered) or ordered[i + 1][1] != "fold":
            continue
        q = ordered[i + 1][0]
        inside = (bp > p) & (bp < q) & bstable
        kinds = {tuple(sig) for sig in bsig[inside]}
        if len(kinds) >= 2:
            print(f"- Two stable orbits coexist for Ω in [{p:.9f}, {q:.9f}] (a grazing corner of {stops[j]}, "
                  f"the fold above it): stable branch points of both inside ({int(np.sum(inside))} points).")


if __name__ == "__main__":
    main()
