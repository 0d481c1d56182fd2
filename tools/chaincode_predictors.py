#!/usr/bin/env python3
"""How much a chain-code step predictor can save on a skeleton.

usage: tools/chaincode_predictors.py SKELETON.json [r]

A prototype of the correction streams of `silva::encode::chaincode` (kind 3,
docs/chaincode.md §7), to judge predictors before writing one. It reads a
skeleton (`silva reconstruct CLOUD --skeleton X.json`, or `silva synth
--truth X.json`), sets the voxel d = mean positive internode length / r
(default r = 5), walks the branches as the encoder does (main extension
first, laterals queued), and picks each node's voxel as `Voxelisation::
Predictive` does: among the voxels within sqrt(3)*d/2 of the node, the one
with the fewest moves from the predicted voxel, ties to the nearer centre.
It prints, per predictor, the order-0 entropy of the corrections in bytes
per internode (branch-first and continuation internodes, x, y and z each a
stream, as kind 3 splits them); the interpolative coder spends about 5 %
more. Then the geometry behind it: step lengths in voxels, the turn
between consecutive internodes of a branch, and their length ratio.

Predictors of a continuation internode's step (a branch's first internode
is never predicted):
  previous      the previous step (the paper's differential prediction)
  none          no prediction: the step itself
  dir x mean    the previous direction times the branch's mean step length
  + frame       corrections in the previous step's frame: axes sorted by
                its largest component, signs flipped to point along it

Needs numpy.
"""
import collections
import itertools
import json
import math
import sys

import numpy as np


def load(path):
    nodes = json.load(open(path))["nodes"]
    pos = np.array([n[:3] for n in nodes])
    parent = [n[4] for n in nodes]
    children = collections.defaultdict(list)
    for i, p in enumerate(parent):
        if p >= 0:
            children[p].append(i)
    return pos, parent, children


def branches(root, children):
    """(fork, chain) per branch in the encoder's order."""
    queue = collections.deque((root, c) for c in children[root])
    while queue:
        fork, at = queue.popleft()
        chain = [at]
        while children[at]:
            queue.extend((at, c) for c in children[at][1:])
            at = children[at][0]
            chain.append(at)
        yield fork, chain


def entropy_bytes(values):
    counts = collections.Counter(values)
    n = len(values)
    return -sum(c * math.log2(c / n) for c in counts.values()) / 8


def predictive_voxel(x, predicted):
    corners = itertools.product(*[(math.floor(t), math.ceil(t)) for t in x])
    near = [np.array(c) for c in corners if np.linalg.norm(np.array(c) - x) <= math.sqrt(3) / 2 + 1e-9]
    return min(near, key=lambda c: (np.abs(c - predicted).sum(), np.linalg.norm(c - x)))


def streams(pos, root, children, d, predict, frame):
    voxel = {root: np.zeros(3, int)}
    out = collections.defaultdict(list)
    for fork, chain in branches(root, children):
        history, previous = [], fork
        for node in chain:
            step = predict(history) if history else np.zeros(3, int)
            base = voxel[previous] + step
            v = predictive_voxel((pos[node] - pos[root]) / d, base)
            correction = v - base
            if frame and history:
                h = history[-1]
                axes = np.argsort(-np.abs(h), kind="stable")
                correction = np.array([correction[a] * (1 if h[a] >= 0 else -1) for a in axes])
            kind = "continuation" if history else "first"
            for axis in range(3):
                out[(kind, axis)].append(int(correction[axis]))
            history.append(v - voxel[previous])
            voxel[node], previous = v, node
    return out


def along_mean(history):
    last = history[-1].astype(float)
    norm = np.linalg.norm(last)
    if norm == 0:
        return np.zeros(3, int)
    mean = np.mean([np.linalg.norm(h) for h in history])
    return np.round(last / norm * mean).astype(int)


def geometry(pos, root, children, d):
    lengths, turns, ratios = [], [], []
    for fork, chain in branches(root, children):
        previous, last = fork, None
        for node in chain:
            step = pos[node] - pos[previous]
            length = np.linalg.norm(step)
            lengths.append(length / d)
            if last is not None and length > 0 and np.linalg.norm(last) > 0:
                cos = step @ last / length / np.linalg.norm(last)
                turns.append(math.degrees(math.acos(max(-1.0, min(1.0, cos)))))
                ratios.append(length / np.linalg.norm(last))
            last, previous = step, node
    return lengths, turns, ratios


def main():
    path = sys.argv[1]
    r = float(sys.argv[2]) if len(sys.argv) > 2 else 5.0
    pos, parent, children = load(path)
    root = parent.index(-1)
    lengths = [np.linalg.norm(pos[i] - pos[p]) for i, p in enumerate(parent) if p >= 0]
    d = np.mean([l for l in lengths if l > 0]) / r
    internodes = len(lengths)
    print(f"{path}: {internodes} internodes, r = {r:g}, d = {d:.4f} m")
    predictors = [
        ("previous", lambda h: h[-1], False),
        ("none", lambda h: np.zeros(3, int), False),
        ("dir x mean", along_mean, False),
        ("previous + frame", lambda h: h[-1], True),
        ("dir x mean + frame", along_mean, True),
    ]
    for name, predict, frame in predictors:
        s = streams(pos, root, children, d, predict, frame)
        first = sum(entropy_bytes(v) for (k, _), v in s.items() if k == "first") / internodes
        rest = sum(entropy_bytes(v) for (k, _), v in s.items() if k == "continuation") / internodes
        print(f"  {name:20s} {first + rest:.3f} B/internode (first {first:.3f}, continuations {rest:.3f})")
    lengths, turns, ratios = geometry(pos, root, children, d)
    q = lambda a: " ".join(f"{v:.2f}" for v in np.percentile(a, [10, 25, 50, 75, 90]))
    print(f"  step length / d, percentiles 10 25 50 75 90: {q(lengths)}")
    print(f"  turn between consecutive internodes, degrees: {q(turns)}")
    print(f"  length ratio of consecutive internodes: {q(ratios)}")


if __name__ == "__main__":
    main()
