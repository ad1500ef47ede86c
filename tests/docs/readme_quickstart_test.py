#!/usr/bin/env python3
"""The README's quick-start numbers are what the quick start prints.

Runs scripts/quickstart.sh against the built tool (SUPERDYNA_SETUP=0: no install, no build) into a
scratch folder and compares the numbers the README states for it -- the ATE line of the written
trajectory and the moving-object precision, recall and static features kept -- with the ones the
script prints. The quick start runs the deterministic pipeline, so they repeat exactly; a change
that moves them fails here until the README and docs/results/quickstart.md are measured again.

Usage: readme_quickstart_test.py README --repo REPO --build BUILD_DIR --work SCRATCH
"""
import argparse
import os
import re
import shutil
import subprocess
import sys


def stated_numbers(readme_text):
    """The numbers the README's quick-start paragraph states, as the strings it prints them."""
    patterns = {
        "ate": r"`ATE \(SE\(3\) aligned\): rmse ([0-9.]+) m`",
        "precision": r"([0-9.]+) % precision",
        "recall": r"([0-9.]+) % recall",
        "static kept": r"([0-9.]+) % of the static objects' features kept",
    }
    stated = {}
    text = " ".join(readme_text.split())  # the paragraph wraps anywhere
    for name, pattern in patterns.items():
        found = re.search(pattern, text)
        if not found:
            sys.exit(f"FAIL: README.md states no quick-start {name} (looked for /{pattern}/)")
        stated[name] = found.group(1)
    return stated


def printed_numbers(output):
    """The same numbers from the quick start's output."""
    ate = re.search(r"^ATE \(SE\(3\) aligned\): rmse ([0-9.]+) m", output, re.M)
    # eval-dynamic's row of all classes: | all | decided | ok | false | missed | unverified |
    # precision | recall | static features kept | moving features dropped |
    row = re.search(r"^\| all \|(.*)\|$", output, re.M)
    if not ate or not row:
        sys.exit("FAIL: the quick start printed no ATE line or no eval-dynamic row:\n" + output)
    cells = [c.strip().rstrip(" %") for c in row.group(1).split("|")]
    return {"ate": ate.group(1), "precision": cells[5], "recall": cells[6],
            "static kept": cells[7]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("readme")
    parser.add_argument("--repo", required=True)
    parser.add_argument("--build", required=True)
    parser.add_argument("--work", required=True)
    args = parser.parse_args()
    with open(args.readme, encoding="utf-8") as f:
        stated = stated_numbers(f.read())
    shutil.rmtree(args.work, ignore_errors=True)
    env = dict(os.environ, SUPERDYNA_SETUP="0", BUILD_DIR=args.build, DEMO_DIR=args.work)
    run = subprocess.run([os.path.join(args.repo, "scripts", "quickstart.sh")], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if run.returncode != 0:
        sys.exit(f"FAIL: the quick start exited {run.returncode}:\n{run.stdout}")
    printed = printed_numbers(run.stdout)
    wrong = [f"{name}: the README says {stated[name]}, the quick start prints {printed[name]}"
             for name in stated if stated[name] != printed[name]]
    if wrong:
        sys.exit("FAIL: README.md's quick-start numbers are stale (measure again and update the "
                 "README and docs/results/quickstart.md):\n  " + "\n  ".join(wrong))
    print("README quick-start numbers match:", ", ".join(f"{k} {v}" for k, v in printed.items()))
    shutil.rmtree(args.work, ignore_errors=True)


if __name__ == "__main__":
    main()
