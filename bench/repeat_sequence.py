#!/usr/bin/env python3
"""Repeats a periodic EuRoC-layout sequence end to end: a long sequence for soak tests.

Usage: bench/repeat_sequence.py SOURCE OUT LAP_SECONDS LAPS

SOURCE is a simulated sequence (the folder holding mav0/) whose motion repeats after LAP_SECONDS:
`superdyna simulate --scene indoor --dynamic none` without --trajectory flies a Lissajous curve
(x period 30 s) with roll and pitch periods of 7 s and 5 s, so it repeats after 210 s. Lap k of
OUT holds SOURCE's frames, IMU samples and ground truth of [t0, t0 + LAP_SECONDS) at times shifted
by k * LAP_SECONDS; images are symbolic links to SOURCE's (nothing is copied). SOURCE must be at
least LAP_SECONDS long, and its ground truth at t0 + LAP_SECONDS must equal the one at t0
(within 1 cm and 0.01 rad: checked, so that a lap boundary is no jump). Static scenes only:
agents and masks are not repeated.
"""

import math
import os
import shutil
import sys

POSITION_TOLERANCE_M = 0.01
ROTATION_TOLERANCE_RAD = 0.01


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def read_rows(path):
    """The header line and the rows (lists of fields) of a EuRoC CSV file."""
    if not os.path.isfile(path):
        fail(f"{path}: file does not exist")
    with open(path) as f:
        lines = f.read().splitlines()
    if not lines or not lines[0].startswith("#"):
        fail(f"{path}: line 1: expected a '#' header")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        fields = [field.strip() for field in line.split(",")]
        if not fields[0].isdigit():
            fail(f"{path}: line {number}: field 'timestamp': not an integer of nanoseconds")
        rows.append(fields)
    if not rows:
        fail(f"{path}: no rows")
    return lines[0], rows


def check_periodic(ground_truth_path, t0, lap_ns):
    """Fails unless the ground-truth pose at t0 + lap equals the one at t0."""
    _, rows = read_rows(ground_truth_path)
    by_time = {int(r[0]): r for r in rows}
    if t0 not in by_time or t0 + lap_ns not in by_time:
        fail(f"{ground_truth_path}: no ground-truth rows at t0 = {t0} and t0 + lap = {t0 + lap_ns} "
             "(is the sequence at least one lap long, and the lap a multiple of the sample period?)")
    a = [float(v) for v in by_time[t0][1:8]]
    b = [float(v) for v in by_time[t0 + lap_ns][1:8]]
    position_error = math.dist(a[0:3], b[0:3])
    dot = abs(sum(x * y for x, y in zip(a[3:7], b[3:7])))
    rotation_error = 2.0 * math.acos(min(1.0, dot))
    if position_error > POSITION_TOLERANCE_M or rotation_error > ROTATION_TOLERANCE_RAD:
        fail(f"{ground_truth_path}: the motion does not repeat after the lap: pose at t0 + lap is "
             f"{position_error:.4f} m and {rotation_error:.4f} rad from the one at t0")


def repeat_rows(header, rows, t0, lap_ns, laps):
    """Rows of [t0, t0 + lap) repeated `laps` times, timestamps shifted by lap."""
    one_lap = [r for r in rows if t0 <= int(r[0]) < t0 + lap_ns]
    out = [header]
    for k in range(laps):
        for r in one_lap:
            out.append(",".join([str(int(r[0]) + k * lap_ns)] + r[1:]))
    return out, len(one_lap)


def write_lines(path, lines):
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def repeat_camera(source_cam, out_cam, t0, lap_ns, laps):
    header, rows = read_rows(os.path.join(source_cam, "data.csv"))
    one_lap = [r for r in rows if t0 <= int(r[0]) < t0 + lap_ns]
    os.makedirs(os.path.join(out_cam, "data"))
    shutil.copy(os.path.join(source_cam, "sensor.yaml"), out_cam)
    lines = [header]
    for k in range(laps):
        for r in one_lap:
            t = int(r[0]) + k * lap_ns
            name = f"{t}.png"
            os.symlink(os.path.abspath(os.path.join(source_cam, "data", r[1])),
                       os.path.join(out_cam, "data", name))
            lines.append(f"{t},{name}")
    write_lines(os.path.join(out_cam, "data.csv"), lines)
    return len(one_lap)


def main():
    if len(sys.argv) != 5:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    source, out = sys.argv[1], sys.argv[2]
    lap_ns = round(float(sys.argv[3]) * 1e9)
    laps = int(sys.argv[4])
    if lap_ns <= 0 or laps < 1:
        fail("LAP_SECONDS must be > 0 and LAPS >= 1")
    src = os.path.join(source, "mav0")
    dst = os.path.join(out, "mav0")
    if os.path.exists(out) and os.listdir(out):
        fail(f"{out}: output folder exists and is not empty")
    _, cam0_rows = read_rows(os.path.join(src, "cam0", "data.csv"))
    t0 = int(cam0_rows[0][0])
    ground_truth = os.path.join(src, "state_groundtruth_estimate0", "data.csv")
    check_periodic(ground_truth, t0, lap_ns)

    frames = repeat_camera(os.path.join(src, "cam0"), os.path.join(dst, "cam0"), t0, lap_ns, laps)
    if os.path.isdir(os.path.join(src, "cam1")):
        repeat_camera(os.path.join(src, "cam1"), os.path.join(dst, "cam1"), t0, lap_ns, laps)
    for stream in ("imu0", "state_groundtruth_estimate0"):
        if not os.path.isdir(os.path.join(src, stream)):
            continue
        os.makedirs(os.path.join(dst, stream))
        shutil.copy(os.path.join(src, stream, "sensor.yaml"), os.path.join(dst, stream))
        header, rows = read_rows(os.path.join(src, stream, "data.csv"))
        lines, _ = repeat_rows(header, rows, t0, lap_ns, laps)
        write_lines(os.path.join(dst, stream, "data.csv"), lines)
    print(f"{out}: {laps} laps of {lap_ns / 1e9:g} s, {frames * laps} frames "
          f"({frames} per lap, {laps * lap_ns / 60e9:.1f} min)")


if __name__ == "__main__":
    main()
