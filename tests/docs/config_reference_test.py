#!/usr/bin/env python3
"""Checks docs/reference/configuration.md against the options the tool really has.

The key list comes from the tool itself: `superdyna run` writes every key of every section with
its effective value to `<output stem>_config.yaml`. A run without --config on a tiny simulated
sequence in visual stereo mode (the one mode that changes no default) therefore writes the
defaults. Every key there must have a row on the page with the same default and a matching type,
and every row on the page must be a key there.

Usage: config_reference_test.py PAGE (--superdyna BINARY --work DIR | --dump CONFIG_YAML)
"""
import argparse
import re
import shutil
import subprocess
import sys
from pathlib import Path


def read_dump(path):
    """{(section, key): value text} of an options file as formatSystemOptions writes it."""
    values = {}
    section = None
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        if not line.strip() or line.lstrip().startswith('#'):
            continue
        if not line.startswith(' '):
            section = line.rstrip(':').strip()
            continue
        key, sep, value = line.strip().partition(':')
        if not sep or section is None:
            sys.exit(f'{path}:{number}: cannot read "{line}"')
        values[(section, key.strip())] = value.strip()
    return values


ROW = re.compile(r'^\|\s*`([a-z0-9_]+)`\s*\|\s*([a-z]+)\s*\|\s*`([^`]*)`\s*\|')


def read_page(path):
    """{(section, key): (type, default, line)} of the page's tables, under `## section` headings."""
    rows = {}
    section = None
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        heading = re.match(r'^## `?([a-z_]+)`?\s*$', line)
        if heading:
            section = heading.group(1)
            continue
        row = ROW.match(line)
        if row and section is not None:
            entry = (section, row.group(1))
            if entry in rows:
                sys.exit(f'{path}:{number}: {section}.{row.group(1)} is documented twice')
            rows[entry] = (row.group(2), row.group(3), number)
    return rows


def type_of(value):
    """The page's type name for a value as the options file writes it."""
    if value.startswith('"'):
        return 'string'
    if value in ('true', 'false'):
        return 'bool'
    if re.fullmatch(r'-?\d+', value):
        return 'integer'
    if re.fullmatch(r'-?[\d.]+(e[-+]?\d+)?|-?inf|nan', value):
        return 'real'
    return 'name'


def dump_from_tool(superdyna, work):
    work = Path(work)
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    sequence = work / 'seq'
    subprocess.run([superdyna, 'simulate', '--out', str(sequence), '--duration', '0.5',
                    '--dynamic', 'none', '--landmarks', '0'], check=True,
                   stdout=subprocess.DEVNULL)
    output = work / 'out' / 'traj.txt'
    output.parent.mkdir()
    subprocess.run([superdyna, 'run', '--dataset', 'euroc', '--path', str(sequence), '--mode',
                    'stereo', '--deterministic', '--max-frames', '2', '--output', str(output)],
                   check=True, stdout=subprocess.DEVNULL)
    return output.with_name('traj_config.yaml')


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('page')
    parser.add_argument('--superdyna')
    parser.add_argument('--work')
    parser.add_argument('--dump')
    args = parser.parse_args()
    if args.dump:
        dump = Path(args.dump)
    elif args.superdyna and args.work:
        dump = dump_from_tool(args.superdyna, args.work)
    else:
        parser.error('give --dump, or --superdyna and --work')
    options = read_dump(dump)
    page = read_page(args.page)
    problems = []
    for (section, key), value in options.items():
        if (section, key) not in page:
            problems.append(f'{section}.{key} (default {value}) is an option but has no row on '
                            f'the page: add it under "## {section}"')
            continue
        documented_type, documented_default, line = page[(section, key)]
        if documented_default != value:
            problems.append(f'{args.page}:{line}: {section}.{key}: the page says default '
                            f'{documented_default}, the tool writes {value}')
        if documented_type != type_of(value):
            problems.append(f'{args.page}:{line}: {section}.{key}: the page says type '
                            f'{documented_type}, the value {value} is {type_of(value)}')
    for (section, key), (_, _, line) in page.items():
        if (section, key) not in options:
            problems.append(f'{args.page}:{line}: {section}.{key} is documented but is not an '
                            f'option (any more): remove or rename its row')
    if problems:
        print(f'configuration reference out of date ({len(problems)} problems; options read '
              f'from {dump}):')
        for problem in problems:
            print('  ' + problem)
        return 1
    print(f'configuration reference: {len(options)} keys in {len(set(s for s, _ in options))} '
          f'sections, each documented with its type and default')
    return 0


if __name__ == '__main__':
    sys.exit(main())
