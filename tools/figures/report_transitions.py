"""The bifurcations located along the rising study's frequency scans, beside the paper's account
(Wagg 2004, section 3: rising between Ω = 0.255 and 0.2561, the second part of the split sticking
phase vanishing near 0.2575, the drop in sticking time near 0.26). Markdown on stdout.

    python3 tools/figures/report_transitions.py rising_scan.h5 [fig5_zoom.h5 ...]
"""
import sys

import h5py
import numpy as np

PAPER = {
    ("rising", "s1"): "between 0.255 and 0.2561 (fig. 4 a–d)",
    ("vanishing", "s1"): "≈ 0.2575 (fig. 5 b)",
}


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: report_transitions.py SCAN.h5 [SCAN2.h5 ...]")
    print("| scan | kind | stop | located Ω | bracket | limit at the bracket | sticking before → after | paper |")
    print("|---|---|---|---|---|---|---|---|")
    for path in sys.argv[1:]:
        with h5py.File(path, "r") as f:
            t = f["transitions"]
            names = [str(n) for n in t["kind"].attrs["names"]]
            stops = [s.decode() if isinstance(s, bytes) else str(s) for s in f["scene/stop_name"][:]]
            scan = f["scan"]
            periodic = scan["periodic"][:]
            for i in range(t["kind"].shape[0]):
                kind = names[int(t["kind"][i])]
                j = int(t["stop"][i])
                stop = stops[j] if j >= 0 else "-"
                lo, hi = t["parameter_low"][i], t["parameter_high"][i]
                if kind == "rising":
                    limit = f"least interior force {t['force_limit'][i]:.1e}"
                elif kind == "vanishing":
                    limit = f"shortest part {t['duration_limit'][i]:.1e} T"
                else:
                    limit = "-"
                change = "-"
                if j >= 0:
                    change = f"{t['sticking_low'][i, j]:.4f} → {t['sticking_high'][i, j]:.4f}"
                paper = PAPER.get((kind, stop), "—")
                print(f"| {path.split('/')[-1]} | {kind} | {stop} | {t['parameter'][i]:.9f} | "
                      f"{hi - lo:.1e} | {limit} | {change} | {paper} |")
            bad = int(np.sum(periodic == 0))
            print(f"| {path.split('/')[-1]} | grid: {len(periodic)} points, "
                  f"{len(periodic) - bad} periodic, {bad} not | | | | | | |")


if __name__ == "__main__":
    main()
