#!/usr/bin/env python3
"""Compares the numeric keys two JSON reports share, to a relative tolerance.

Usage: compare_json.py A.json B.json KEY [KEY ...] [--rtol 1e-6]
Exits 1 (printing every mismatch) when a key is missing or differs.
"""
import json
import sys


def main():
    args = sys.argv[1:]
    rtol = 1e-6
    if "--rtol" in args:
        i = args.index("--rtol")
        rtol = float(args[i + 1])
        del args[i:i + 2]
    a_file, b_file, keys = args[0], args[1], args[2:]
    a, b = json.load(open(a_file)), json.load(open(b_file))
    failures = 0
    for key in keys:
        if key not in a or key not in b:
            print(f"missing key {key}")
            failures += 1
            continue
        x, y = float(a[key]), float(b[key])
        ok = abs(x - y) <= rtol * max(abs(x), abs(y), 1e-300)
        print(f"{'ok  ' if ok else 'FAIL'} {key}: {x!r} vs {y!r}")
        failures += not ok
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
