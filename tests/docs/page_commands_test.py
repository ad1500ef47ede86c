#!/usr/bin/env python3
"""Runs the command blocks of a documentation page that are marked for testing.

A block is marked by the line `<!-- docs-test -->` right before its ```sh fence. The marked blocks
run in page order, each with bash in one fresh work folder, so later blocks see what earlier ones
wrote. `build/bin/superdyna` in a command becomes the tool under test and `configs/` the
repository's configs. Blocks that need ROS bag support are skipped when the build has none.

Usage: getting_started_test.py PAGE --superdyna BINARY --repo REPO_DIR --work DIR [--no-rosbag]
"""
import argparse
import re
import shutil
import subprocess
import sys
from pathlib import Path

MARKER = '<!-- docs-test -->'


def marked_blocks(page):
    """(line, command text) of each marked ```sh block of the page."""
    lines = Path(page).read_text().splitlines()
    blocks = []
    for i, line in enumerate(lines):
        if line.strip() != MARKER:
            continue
        fence = i + 1
        if fence >= len(lines) or lines[fence].strip() != '```sh':
            sys.exit(f'{page}:{i + 1}: {MARKER} must be followed directly by a ```sh block')
        end = fence + 1
        while end < len(lines) and lines[end].strip() != '```':
            end += 1
        if end == len(lines):
            sys.exit(f'{page}:{fence + 1}: the marked block is not closed')
        blocks.append((fence + 1, '\n'.join(lines[fence + 1:end])))
    return blocks


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('page')
    parser.add_argument('--superdyna', required=True)
    parser.add_argument('--repo', required=True)
    parser.add_argument('--work', required=True)
    parser.add_argument('--no-rosbag', action='store_true')
    args = parser.parse_args()
    blocks = marked_blocks(args.page)
    if not blocks:
        sys.exit(f'{args.page}: no block is marked with {MARKER}')
    work = Path(args.work)
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    configs = str(Path(args.repo).resolve() / 'configs') + '/'
    for line, block in blocks:
        command = re.sub(r'(?<![\w/.])build/bin/superdyna\b', args.superdyna, block)
        command = re.sub(r'(?<![\w/.])configs/', configs, command)
        if args.no_rosbag and 'rosbag' in command:
            print(f'-- {args.page}:{line}: skipped (this build has no ROS bag support)\n{block}')
            continue
        print(f'-- {args.page}:{line}\n{block}', flush=True)
        result = subprocess.run(['bash', '-euo', 'pipefail', '-c', command], cwd=work,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if result.returncode != 0:
            print(result.stdout[-4000:])
            print(f'FAILED: the block at {args.page}:{line} exited with {result.returncode}')
            return 1
    print(f'{len(blocks)} marked command blocks of {args.page} ran')
    return 0


if __name__ == '__main__':
    sys.exit(main())
