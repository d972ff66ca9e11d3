"""Wagg (2004), fig. 6: the sticking trajectory of the paper's mass 1 (stop s1, our mass 0) in
(t, x2, x2') space, solid, and the boundary dS of the sticking region, dashed: (a) just before
rising (Ω = 0.2560), (b) just after (Ω = 0.2561), where the orbit leaves the region for a while.

While mass i is held by a fixed stop at s (x_i = s, x_i' = 0, x_i'' = 0), row i of
M x'' = f(t) - C x' - K x + W λ gives the contact force (M diagonal, so row i has no other
acceleration):  σ λ = sum_j (C_ij v_j + K_ij x_j) - f_i(t),  σ = +1 for a lower stop (the force
pushes x_i up), -1 for an upper one, with x_i = s, v_i = 0. For the paper's system this is -F_2 of
its eq. (12). For a 2-mass chain, λ = 0 is solved for the other mass's velocity:
    v_b(t) = (f_i(t) - K_ii s - K_ij x_j(t)) / C_ij,
drawn at x_j(t) of the trajectory. The sign convention is checked against the simulator's recorded
least contact force (/contacts force_min), and the script stops if they disagree.

    vibro run experiments/wagg2004/fig6_sticking_boundary.yaml -o fig6.h5
    python3 tools/figures/fig6_sticking_boundary.py fig6.h5 OUTDIR   # OUTDIR/fig6_sticking_boundary.{png,pdf}
"""
import common as c
import matplotlib.pyplot as plt
import numpy as np

STOP = 0                  # s1, on the paper's mass 1 (our mass 0)
# Agreement of the recorded least force with the formula: the recorded value comes from the exact
# flow; the formula is evaluated from sampled states (exact too) and interpolated to t_force_min by
# a parabola through the 3 nearest samples (dt = T/4000 ≈ 6e-3: error ~ dt^3 |λ'''| ≪ 1e-6).
FORCE_TOL = 1e-6
STUCK_TOL = 1e-9          # x_i - s and v_i while held, relative to the orbit's amplitudes


def contact_force(scene, run, stop, sel):
    i, s = int(scene.stop_mass[stop]), float(scene.stop_position[stop])
    sigma = {"lower": 1.0, "upper": -1.0}[scene.stop_kind[stop]]
    x = run.x[sel].copy()
    v = run.v[sel].copy()
    x[:, i], v[:, i] = s, 0.0
    f = scene.forcing(run.t[sel], run.omega)
    return sigma * (v @ scene.C[i] + x @ scene.K[i] - f[:, i])


def boundary_velocity(scene, run, stop, j, sel):
    i, s = int(scene.stop_mass[stop]), float(scene.stop_position[stop])
    if scene.C[i, j] == 0:
        c.fail(f"C[{i},{j}] = 0: λ does not depend on v_{j}, the boundary is not a velocity")
    f = scene.forcing(run.t[sel], run.omega)[:, i]
    return (f - scene.K[i, i] * s - scene.K[i, j] * run.x[sel, j]) / scene.C[i, j]


def check_contact(scene, run, stop, a, b, fmin, tfmin):
    """The formula's force on the samples of one held interval vs the recorded least force."""
    sel = (run.t >= a) & (run.t <= b)
    if np.count_nonzero(sel) < 3:
        c.fail(f"contact [{a}, {b}] has fewer than 3 samples")
    i = int(scene.stop_mass[stop])
    dx = np.max(np.abs(run.x[sel, i] - scene.stop_position[stop])) / np.max(np.abs(run.x))
    dv = np.max(np.abs(run.v[sel, i])) / np.max(np.abs(run.v))
    if dx > STUCK_TOL or dv > STUCK_TOL:
        c.fail(f"mass {i} is not at rest on {scene.stop_name[stop]} during [{a}, {b}]: {dx:.1e}, {dv:.1e}")
    lam = contact_force(scene, run, stop, sel)
    ts = run.t[sel]
    near = np.argsort(np.abs(ts - tfmin))[:3]
    coef = np.polyfit(ts[near] - tfmin, lam[near], 2)
    at_tmin = coef[-1]
    if abs(at_tmin - fmin) > FORCE_TOL:
        c.fail(f"sign/formula check failed on [{a:.6f}, {b:.6f}]: recorded force_min {fmin:.9g} at "
               f"t = {tfmin:.6f}, formula there {at_tmin:.9g} (samples' min {lam.min():.9g})")
    return lam.min(), at_tmin


def main():
    (path,), outdir = c.args(1, 1, "FIG6.h5 OUTDIR")
    scene, runs = c.read_runs(path)
    if scene.n != 2:
        c.fail(f"the boundary in (t, x2, x2') is drawn for 2 masses; this scene has {scene.n}")
    if np.any(np.abs(scene.M - np.diag(np.diag(scene.M))) > 0):
        c.fail("M is not diagonal")
    if scene.stop_kind[STOP] == "between" or np.any(scene.stop_amplitude != 0):
        c.fail("stop s1 must be a fixed stop on one mass")
    i = int(scene.stop_mass[STOP])
    j = 1 - i
    fig = plt.figure(figsize=(11, 5))
    for p, run in enumerate(runs):
        per = c.periodicity(run)
        ivs = sorted(c.sticking_intervals(run, STOP))
        cs = run.contacts
        if not ivs:
            c.fail(f"Ω = {run.omega}: no sticking on {scene.stop_name[STOP]}")
        # The first held phase, with any later part of it that starts within half a period (a split phase).
        first = ivs[0][0]
        group = [(a, b) for a, b in ivs if a < first + 0.5 * run.period]
        ta, tb = group[0][0], group[-1][1]
        if tb > run.t[-1]:
            c.fail("the sticking phase runs past the recorded samples")
        checks = []
        for a, b in group:
            k = np.flatnonzero((cs["stop"] == STOP) & (cs["t_start"] == a))[0]
            checks.append((a, b, cs["force_min"][k], cs["t_force_min"][k],
                           *check_contact(scene, run, STOP, a, b, cs["force_min"][k], cs["t_force_min"][k])))
        ax = fig.add_subplot(1, len(runs), p + 1, projection="3d")
        win = (run.t >= ta) & (run.t <= tb)
        t = run.t[win] - ta
        xb, vb = run.x[win, j], boundary_velocity(scene, run, STOP, j, win)
        held = np.zeros(len(run.t), bool)
        for a, b in group:
            held |= (run.t >= a) & (run.t <= b)
        held = held[win]
        first_label = True
        for seg in np.split(np.arange(len(t)), np.flatnonzero(np.diff(held.astype(int))) + 1):
            if held[seg[0]]:
                ax.plot(t[seg], xb[seg], run.v[win, j][seg], "-", color="black", lw=1.4,
                        label="sticking trajectory" if first_label else None)
                first_label = False
            else:
                seg = np.concatenate([[seg[0] - 1], seg, [seg[-1] + 1]])
                ax.plot(t[seg], xb[seg], run.v[win, j][seg], "-", color="tab:red", lw=1.0,
                        label=f"{c.mass_label(i)} off {scene.stop_name[STOP]} (rising)")
        # The boundary leaves the trajectory's velocity range steeply (|v_b| ~ 1/|C_ij|): drawn inside
        # that range only (3-D axes do not clip).
        vt = run.v[win, j]
        zlo, zhi = vt.min() - 0.15 * np.ptp(vt), vt.max() + 0.15 * np.ptp(vt)
        vb = np.where((vb >= zlo) & (vb <= zhi), vb, np.nan)
        ax.set_zlim(zlo, zhi)
        ax.plot(t, xb, vb, "--", color="tab:blue", lw=1.2, label="$\\partial S$: contact force $= 0$")
        ax.set_xlabel("$t - t_s$")
        ax.set_ylabel(c.mass_label(j))
        ax.set_zlabel(c.velocity_label(j))
        ax.view_init(elev=12, azim=-72)
        ax.set_box_aspect(None, zoom=0.85)     # room for the z label
        ax.yaxis.set_major_locator(plt.MaxNLocator(4))
        tag = "ab"[p] if len(runs) == 2 else str(p)
        when = "before rising" if len(group) == 1 else "after rising"
        ax.set_title(f"({tag}) $\\Omega$ = {run.omega:g}, {when}\n{per.text()}", color=per.colour(), fontsize=8.5)
        ax.legend(loc="upper left", fontsize=7)
        # Facts: the recorded and computed least forces; where the orbit is outside the region.
        out_sel = ~held
        excursion = (f"; off the stop for {np.ptp(t[out_sel]) + (run.t[1] - run.t[0]):.4f} time units "
                     f"({(group[1][0] - group[0][1]):.4f} between the parts) with {c.mass_label(j).strip('$')} in "
                     f"[{xb[out_sel].min():.4f}, {xb[out_sel].max():.4f}]") if np.any(out_sel) else ""
        print(f"fig6 Ω = {run.omega:g}: {per.text()}; {len(group)} held part(s) of {scene.stop_name[STOP]}, "
              f"{tb - ta:.4f} time units{excursion}")
        for a, b, fmin, tfmin, smin, at in checks:
            print(f"  part [{a - ta:.4f}, {b - ta:.4f}]: recorded force_min {fmin:.9f} at t - t_s = {tfmin - ta:.5f}; "
                  f"formula there {at:.9f} (diff {at - fmin:.1e}), least over the samples up to the release {smin:.9f}")
    fig.suptitle(f"Wagg (2004) fig. 6: sticking of the paper's mass 1 on {scene.stop_name[STOP]} "
                 f"({c.mass_label(i)} = {scene.stop_position[STOP]:g}) in $(t, x_2, \\dot x_2)$", fontsize=10)
    fig.tight_layout()
    out = c.save(fig, outdir, "fig6_sticking_boundary")
    print(f"  wrote {out}")


if __name__ == "__main__":
    main()
