#!/usr/bin/env python3
"""Alternate two relief binaries on `bench terrain` and print the median ratio per figure.

    scripts/bench-ab.py --a "/tmp/relief-before bench" --b "target/release/relief bench terrain" \
        --rounds 5 -- --size 640x360 --frames 10

Each round runs A then B (the order alternates every round so drift cancels) with the given
bench arguments and `--json`; per configuration and figure (primary_ms, frame_ms) it prints
both medians and the median over rounds of B/A. Reads the report of either the old
`relief bench` (top-level `configs`) or the subcommand report (`details.configs`).
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys


def configs(report):
    if "configs" in report:
        return report["configs"]
    return report["details"]["configs"]


def run(cmd, extra):
    env = dict(os.environ, NODEVICE_SELECT="1")
    out = subprocess.run(shlex.split(cmd) + extra + ["--json"], capture_output=True, text=True,
                         env=env, check=True).stdout
    return {c["name"]: c for c in configs(json.loads(out))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--a", required=True)
    ap.add_argument("--b", required=True)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("extra", nargs="*")
    args = ap.parse_args()
    figures = ["primary_ms", "frame_ms"]
    runs = {"a": [], "b": []}
    for r in range(args.rounds):
        order = ["a", "b"] if r % 2 == 0 else ["b", "a"]
        for which in order:
            runs[which].append(run(getattr(args, which), args.extra))
        print(f"round {r + 1}/{args.rounds} done", file=sys.stderr)
    print(f"{'config':<24} {'figure':<11} {'A median':>9} {'B median':>9} {'B/A median':>10}")
    worst = 0.0
    for name in runs["a"][0]:
        for f in figures:
            a = [x[name][f] for x in runs["a"]]
            b = [x[name][f] for x in runs["b"]]
            ratio = statistics.median(bb / aa for aa, bb in zip(a, b))
            worst = max(worst, abs(ratio - 1.0))
            print(f"{name:<24} {f:<11} {statistics.median(a):9.3f} {statistics.median(b):9.3f} "
                  f"{ratio:10.3f}")
    print(f"largest deviation of a median ratio from 1: {worst * 100:.1f}%")


if __name__ == "__main__":
    main()
