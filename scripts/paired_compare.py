#!/usr/bin/env python3
"""Two evaluations of the same scenes, compared scene by scene.

    python3 scripts/paired_compare.py BEFORE AFTER [BEFORE AFTER ...]

Each BEFORE and AFTER is a study folder of `camplace evaluate` (its results.jsonl) over the
same placement, method, seed and scenarios, run by two builds or two settings. For each
pair it prints success and verified success (accepted and correct) before and after, the
discordant scenes, and the exact McNemar test's one-sided p that AFTER is lower (a binomial
test of the discordant scenes at one half), with the median position and rotation errors
of the correct poses and their paired median difference. Exits 1 when a folder is missing,
holds other scenes than its partner, or a rate is lower at the 5 % level.
"""
import json
import statistics
import sys
from math import comb


def read(folder):
    path = f"{folder}/results.jsonl"
    try:
        with open(path) as f:
            rows = [json.loads(line) for line in f if line.strip()]
    except OSError as e:
        sys.exit(f"{path}: {e.strerror}")
    except json.JSONDecodeError as e:
        sys.exit(f"{path}: expected one JSON record a line ({e})")
    return {(r["placement"], r["method"], r["seed"], r["scenario"]): r for r in rows}


def lower_p(worse, better):
    """One-sided exact McNemar: P(at least `worse` of the discordant pairs go against AFTER)."""
    n = worse + better
    if n == 0:
        return 1.0
    return sum(comb(n, k) for k in range(worse, n + 1)) / 2**n


def verified(r):
    return bool(r.get("success")) and r.get("verdict") == "accepted"


def main(args):
    if not args or len(args) % 2:
        sys.exit(__doc__)
    failed = False
    for before_dir, after_dir in zip(args[::2], args[1::2]):
        before, after = read(before_dir), read(after_dir)
        if before.keys() != after.keys():
            sys.exit(f"{after_dir}: expected the scenes of {before_dir}, found {len(after)} against {len(before)}")
        keys = sorted(before)
        label = f"{keys[0][0]} {keys[0][1]} ({len(keys)} scenes)" if keys else "(no scenes)"
        print(f"{before_dir} -> {after_dir}: {label}")
        for name, judge in (("success", lambda r: bool(r.get("success"))), ("verified", verified)):
            b = [judge(before[k]) for k in keys]
            a = [judge(after[k]) for k in keys]
            worse = sum(1 for x, y in zip(b, a) if x and not y)
            better = sum(1 for x, y in zip(b, a) if y and not x)
            p = lower_p(worse, better)
            flag = "LOWER" if p < 0.05 else "kept"
            failed |= p < 0.05
            print(f"  {name:9} {sum(b):4} -> {sum(a):4}  lost {worse}, gained {better}, one-sided p {p:.3f}  {flag}")
        for field, unit in (("position_error_mm", "mm"), ("rotation_error_deg", "deg")):
            eb = [before[k][field] for k in keys if before[k].get("success")]
            ea = [after[k][field] for k in keys if after[k].get("success")]
            both = [after[k][field] - before[k][field] for k in keys if before[k].get("success") and after[k].get("success")]
            if eb and ea:
                print(f"  median {field}: {statistics.median(eb):.3f} -> {statistics.median(ea):.3f} {unit}"
                      f" (paired median difference {statistics.median(both):+.3f})")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main(sys.argv[1:])
