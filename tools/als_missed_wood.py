#!/usr/bin/env python3
"""Missed truth wood of an airborne reconstruction.

usage: tools/als_missed_wood.py TRUTH.json RECON.json CLOUD.xyz [--tol 0.5] [--rmin 0.05]

Samples truth internodes of mean radius >= rmin every 5 cm (as
src/eval/compare.rs), marks samples farther than tol from the
reconstruction (all internodes sampled at 5 cm), groups the missed samples
into runs along the truth tree, and prints per run: height range above the
truth base, length, mean radius, the count of cloud points within tol of the
run (and within 0.25 m), distance of the run to the reconstruction.
Then attributes the returns within tol of missed wood: how many lie nearer
other truth wood (any radius) than the missed wood, and how many the
reconstruction passes within 0.3 m of (returns it used for other wood).

Inputs as `silva eval --synthetic 20 --scan als` makes them (tree i, 1-based,
is species [oak, birch, poplar, pine][(i-1)%4], seed i, anchored at
155000+30(i-1), 463000, 1.5), e.g. oak seed 5:

  silva synth --species oak --seed 5 --scan als --anchor 155120,463000,1.5 \
      -o oak5.xyz --truth oak5-truth.json
  silva reconstruct oak5.xyz --mode airborne --skeleton oak5-rec.json
  python3 tools/als_missed_wood.py oak5-truth.json oak5-rec.json oak5.xyz

Needs numpy and scipy.
"""
import json
import sys

import numpy as np
from scipy.spatial import cKDTree

STEP = 0.05


def load_skeleton(path):
    d = json.load(open(path))
    origin = np.array(d["anchor"]["origin"], dtype=float)
    nodes = np.array(d["nodes"], dtype=float)
    pos = nodes[:, :3] + origin
    return pos, nodes[:, 3], nodes[:, 4].astype(int), origin


def samples(pos, rad, parent, rmin):
    out, seg = [], []
    for c in range(len(pos)):
        p = parent[c]
        if p < 0 or (rad[p] + rad[c]) * 0.5 < rmin:
            continue
        a, b = pos[p], pos[c]
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / STEP)))
        t = (np.arange(n) + 0.5) / n
        out.append(a + np.outer(t, b - a))
        seg.extend([c] * n)
    return np.vstack(out), np.array(seg)


def main():
    args = sys.argv[1:]
    tol = float(args[args.index("--tol") + 1]) if "--tol" in args else 0.5
    rmin = float(args[args.index("--rmin") + 1]) if "--rmin" in args else 0.05
    truth_path, recon_path, cloud_path = args[:3]
    tpos, trad, tpar, torigin = load_skeleton(truth_path)
    rpos, rrad, rpar, _ = load_skeleton(recon_path)
    cloud = np.loadtxt(cloud_path, usecols=(0, 1, 2))
    ts, tseg = samples(tpos, trad, tpar, rmin)
    rs, _ = samples(rpos, rrad, rpar, 0.0)
    d_rec = cKDTree(rs).query(ts)[0]
    miss = d_rec > tol
    tall, _ = samples(tpos, trad, tpar, 0.0)
    prec = (cKDTree(tall).query(rs)[0] <= tol).mean()
    print(f"recall {1 - miss.mean():.3f} precision {prec:.3f} "
          f"truth samples {len(ts)} missed {miss.sum()} ({miss.sum() * STEP:.1f} m)")
    # Group missed internodes into runs: connected through parent links.
    missed_nodes = set(tseg[miss].tolist())
    children = {}
    for c, p in enumerate(tpar):
        children.setdefault(p, []).append(c)
    seen, runs = set(), []
    for n in sorted(missed_nodes):
        if n in seen:
            continue
        stack, run = [n], []
        while stack:
            m = stack.pop()
            if m in seen or m not in missed_nodes:
                continue
            seen.add(m)
            run.append(m)
            stack.extend(children.get(m, []))
            if tpar[m] >= 0:
                stack.append(tpar[m])
        runs.append(run)
    ctree = cKDTree(cloud)
    base_z = torigin[2]
    rows = []
    for run in runs:
        sel = miss & np.isin(tseg, run)
        pts = ts[sel]
        near = set()
        for lst in ctree.query_ball_point(pts, tol):
            near.update(lst)
        near25 = set()
        for lst in ctree.query_ball_point(pts, 0.25):
            near25.update(lst)
        r = np.mean([(trad[m] + trad[tpar[m]]) * 0.5 for m in run])
        z = pts[:, 2] - base_z
        horiz = np.linalg.norm(pts[:, :2] - torigin[:2], axis=1)
        rows.append((sel.sum() * STEP, z.min(), z.max(), horiz.min(), horiz.max(), r,
                     len(near), len(near25), d_rec[sel].max(), pts.mean(axis=0) - torigin))
    rows.sort(key=lambda x: -x[0])
    print(f"{'len_m':>6} {'z_lo':>5} {'z_hi':>5} {'hd_lo':>5} {'hd_hi':>5} {'r_cm':>5} "
          f"{'pts.5':>5} {'pts.25':>6} {'dmax':>5}  centre(rel)")
    for L, zl, zh, hl, hh, r, n, n25, dm, c in rows:
        print(f"{L:6.2f} {zl:5.1f} {zh:5.1f} {hl:5.1f} {hh:5.1f} {r * 100:5.1f} {n:5d} {n25:6d} "
              f"{dm:5.2f}  ({c[0]:.1f},{c[1]:.1f},{c[2]:.1f})")
    tot = sum(x[0] for x in rows)
    with_data = sum(x[0] for x in rows if x[6] > 0)
    print(f"missed {tot:.1f} m, of which {with_data:.1f} m in runs with cloud points within {tol} m")
    # Per-sample: missed samples that have a cloud point within tol.
    cnt = np.array([len(lst) for lst in ctree.query_ball_point(ts[miss], tol)])
    if len(cnt) == 0:
        return
    print(f"missed samples with >=1 point within {tol} m: {(cnt > 0).mean():.2f}; "
          f">=3: {(cnt >= 3).mean():.2f}")
    near = sorted(set(i for lst in ctree.query_ball_point(ts[miss], tol) for i in lst))
    if not near:
        print(f"no return within {tol} m of missed wood")
        return
    pts = cloud[near]
    d_missed = cKDTree(ts[miss]).query(pts)[0]
    d_wood = cKDTree(tall).query(pts)[0]
    d_recon = cKDTree(rs).query(pts)[0]
    own = d_missed <= d_wood + 1e-6
    print(f"{len(pts)} returns within {tol} m of missed wood: {(~own).sum()} nearer other "
          f"truth wood, {own.sum()} nearest the missed wood ({(own & (d_missed <= 0.25)).sum()} "
          f"within 0.25 m of it); the reconstruction passes within 0.3 m of "
          f"{(d_recon <= 0.3).sum()}")


if __name__ == "__main__":
    main()
