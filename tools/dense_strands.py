#!/usr/bin/env python3
"""Short laterals of a dense reconstruction that duplicate the true branch
they fork from.

usage: tools/dense_strands.py RECON.json TRUTH.json [--short 0.5]

Samples the truth's internodes every centimetre and labels each sample with
its true branch (a chain of main extensions: the trunk, or a lateral and its
own main extensions). Labels every node of the reconstruction with the
branch of its nearest sample. A reconstructed lateral (a fork's child other
than the first, with its chain of first children) lies on the *same* true
branch as its fork when its most common label is the fork's or the fork's
main extension's; otherwise on *another*. Prints the count and length of the
laterals of each kind, shorter and longer than `--short` metres; then, for
the short same-branch ones, the true radius at their tip and how far the tip
lies from the true axis, in bands of true radius. A lateral whose tip lies
about the true radius off the axis runs along the bark of the branch it
forks from: a second chain on the other side of a limb whose bark a bin
splits into two arcs (see `dense::Params::strand_reach_bins`).

Inputs as `silva eval --synthetic 20 --scan tls --density 1000
--no-occlusion` makes them (tree i, 1-based, is species [oak, birch, poplar,
pine][(i-1)%4], seed i), e.g. oak seed 1:

  silva synth --species oak --seed 1 --scan tls --density 1000 --no-occlusion \
      -o oak1.xyz --truth oak1-truth.json
  silva reconstruct oak1.xyz --skeleton oak1-rec.json
  python3 tools/dense_strands.py oak1-rec.json oak1-truth.json

Both skeletons are compared in absolute coordinates (their anchors differ).
Needs numpy and scipy.
"""
import argparse
import collections
import json

import numpy as np
from scipy.spatial import cKDTree

SAMPLE_M = 0.01
RADIUS_BANDS = [(0.0, 0.01), (0.01, 0.02), (0.02, 0.05), (0.05, 0.10), (0.10, 10.0)]


def load(path):
    """Absolute positions, radii, parents and children of a silva skeleton."""
    doc = json.load(open(path))
    nodes = np.array([n[:4] for n in doc["nodes"]], dtype=float)
    positions = nodes[:, :3] + np.array(doc["anchor"]["origin"])
    parents = [int(n[4]) for n in doc["nodes"]]
    children = collections.defaultdict(list)
    for i, p in enumerate(parents):
        if p >= 0:
            children[p].append(i)
    return positions, nodes[:, 3], parents, children


def branch_labels(parents, children):
    """Branch of each node: the root's is 0, each lateral starts a new one."""
    label = [0] * len(parents)
    count = 1
    for v in range(len(parents)):  # parents precede children
        for rank, c in enumerate(children[v]):
            if rank == 0:
                label[c] = label[v]
            else:
                label[c] = count
                count += 1
    return label


def truth_samples(positions, radii, parents, labels):
    """Samples every SAMPLE_M along each internode: position, branch, radius."""
    points, branch, radius = [], [], []
    for child in range(1, len(parents)):
        a, b = positions[parents[child]], positions[child]
        n = max(1, int(np.linalg.norm(b - a) / SAMPLE_M))
        for t in (np.arange(n) + 0.5) / n:
            points.append(a + (b - a) * t)
            branch.append(labels[child])
            radius.append(radii[child])
    return np.array(points), np.array(branch), np.array(radius)


def lateral_chain(children, first):
    chain = [first]
    while children[chain[-1]]:
        chain.append(children[chain[-1]][0])
    return chain


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("recon")
    ap.add_argument("truth")
    ap.add_argument("--short", type=float, default=0.5)
    args = ap.parse_args()

    t_pos, t_rad, t_par, t_kids = load(args.truth)
    samples, sample_branch, sample_radius = truth_samples(
        t_pos, t_rad, t_par, branch_labels(t_par, t_kids)
    )
    r_pos, _, r_par, r_kids = load(args.recon)
    dist, nearest = cKDTree(samples).query(r_pos)
    label = sample_branch[nearest]

    kinds = collections.defaultdict(lambda: [0, 0.0])
    strands = []
    for fork in range(len(r_pos)):
        own = {label[fork]} | ({label[r_kids[fork][0]]} if r_kids[fork] else set())
        for first in r_kids[fork][1:]:
            chain = lateral_chain(r_kids, first)
            length = sum(np.linalg.norm(r_pos[c] - r_pos[r_par[c]]) for c in chain)
            common = collections.Counter(label[c] for c in chain).most_common(1)[0][0]
            same = common in own
            short = length < args.short
            kinds[("same branch" if same else "another branch", short)][0] += 1
            kinds[("same branch" if same else "another branch", short)][1] += length
            if same and short:
                tip = chain[-1]
                strands.append((sample_radius[nearest[tip]], dist[tip], length))

    for (kind, short), (count, length) in sorted(kinds.items()):
        size = f"< {args.short} m" if short else f">= {args.short} m"
        print(f"laterals on {kind:14} {size:9}: {count:5}, {length:7.1f} m")
    if not strands:
        return
    strands = np.array(strands)
    print("short laterals on the same branch, by true radius at the tip:")
    for lo, hi in RADIUS_BANDS:
        band = (strands[:, 0] >= lo) & (strands[:, 0] < hi)
        if band.any():
            print(
                f"  {lo * 100:4.0f}-{hi * 100:<4.0f} cm: {band.sum():5} laterals, "
                f"{strands[band, 2].sum():6.1f} m, tip a median "
                f"{np.median(strands[band, 1]) * 100:4.1f} cm off the true axis"
            )


if __name__ == "__main__":
    main()
