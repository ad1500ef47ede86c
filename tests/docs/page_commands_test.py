#!/usr/bin/env python3
"""Runs the command blocks of a documentation page that are marked for testing.

A block is marked by an HTML comment right before its fence (the site does not show it):

  <!-- docs-test -->           the next ```sh block runs as it is;
  <!-- docs-test: TWIN -->     it runs beside a short simulated twin of a dataset (TWINS below),
                               built in the work folder, before the first block that names it,
                               under the names the page uses (MH_01_easy, sequences/00, ...);
  <!-- docs-test: TWIN writes FILE from BASE -->
                               the next ```yaml block is a section to put into a copy of BASE
                               (a repository path): its top-level sections replace BASE's, and
                               the result is written to FILE for the blocks after it.

A marker may end with a note after a semicolon, for readers of the page's source: how the twin
differs from the real dataset (`<!-- docs-test: tumvi; pinhole cameras, not fisheye -->`).

The marked blocks run in page order, each with bash -euo pipefail in one fresh work folder, so
later blocks see what earlier ones wrote. Before a block runs, `build/bin/superdyna` becomes the
tool under test, `configs/` the repository's configs and a documented placeholder folder
`/path/to/NAME/` the twin's folder `WORK/NAME/`; nothing else of the command is changed (no flag
is added or removed). Blocks that read or write ROS bags, and the twins made of bags, are skipped
when the build has no ROS bag support (--no-rosbag); the test then exits 77 (skipped) after
running the others. The unmarked ```sh blocks are counted and listed, so that a reviewer sees
what the test does not cover.

Usage: page_commands_test.py PAGE --superdyna BINARY --repo REPO_DIR --work DIR [--no-rosbag]
"""
import argparse
import math
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

MARKER = re.compile(r'<!-- docs-test(?::\s*(?P<twin>[\w-]+)'
                    r'(?:\s+writes\s+(?P<file>\S+)\s+from\s+(?P<base>\S+))?)?'
                    r'(?:\s*;\s*(?P<note>[^>]*?))?\s*-->$')
SKIPPED = 77


class Runner:
    """Runs the tool (for the twins) and the page's commands in the work folder."""

    def __init__(self, args):
        self.superdyna = args.superdyna
        self.repo = Path(args.repo).resolve()
        self.work = Path(args.work).resolve()
        self.rosbag = not args.no_rosbag
        self.built = set()

    def tool(self, *arguments):
        result = subprocess.run([self.superdyna, *map(str, arguments)], cwd=self.work,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if result.returncode != 0:
            print(result.stdout[-4000:])
            raise RuntimeError(f'building a twin: superdyna {" ".join(map(str, arguments))} '
                               f'exited with {result.returncode}')

    def ensure(self, twin):
        if twin in self.built:
            return
        started = time.monotonic()
        TWINS[twin]['build'](self)
        self.built.add(twin)
        print(f'-- twin {twin}: {TWINS[twin]["what"]} ({time.monotonic() - started:.1f} s)',
              flush=True)

    def substitute(self, text):
        text = re.sub(r'(?<![\w/.])build/bin/superdyna\b', self.superdyna, text)
        text = re.sub(r'(?<![\w/.])configs/', str(self.repo / 'configs') + '/', text)
        return re.sub(r'/path/to/(?=[\w.-]+/)', str(self.work) + '/', text)


# ---- small helpers for the twins (Python's standard library only) -------------------------------

def simulate(runner, out, *options, duration=3):
    """A short simulated sequence: few ground-truth landmarks, `duration` seconds."""
    runner.tool('simulate', '--out', out, '--duration', duration, '--landmarks', 100, *options)


def sensor_yaml_matrix(file):
    """T_BS of an EuRoC sensor.yaml as a 4x4 list of rows."""
    match = re.search(r'T_BS:.*?data:\s*\[([^\]]*)\]', Path(file).read_text(), re.S)
    values = [float(v) for v in match.group(1).replace('\n', ' ').split(',')]
    return [values[4 * r:4 * r + 4] for r in range(4)]


def sensor_yaml_intrinsics(file):
    text = Path(file).read_text()
    fx, fy, cx, cy = (float(v) for v in re.search(r'intrinsics:\s*\[([^\]]*)\]', text)
                      .group(1).split(','))
    width, height = (int(v) for v in re.search(r'resolution:\s*\[([^\]]*)\]', text)
                     .group(1).split(','))
    return fx, fy, cx, cy, width, height


def sensor_yaml_number(file, key):
    return float(re.search(rf'^{key}:\s*(\S+)', Path(file).read_text(), re.M).group(1))


def matmul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def rigid_inverse(t):
    rotation_t = [[t[c][r] for c in range(3)] for r in range(3)]
    translation = [-sum(rotation_t[r][k] * t[k][3] for k in range(3)) for r in range(3)]
    return [rotation_t[r] + [translation[r]] for r in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def pose_matrix(p, q_wxyz):
    w, x, y, z = q_wxyz
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y), p[0]],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x), p[1]],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y), p[2]],
            [0.0, 0.0, 0.0, 1.0]]


def euroc_ground_truth(mav0):
    """{t_ns: (position, quaternion wxyz)} of a simulated sequence's body."""
    poses = {}
    for line in (mav0 / 'state_groundtruth_estimate0/data.csv').read_text().splitlines():
        if line.startswith('#') or not line.strip():
            continue
        v = line.split(',')
        poses[int(v[0])] = ([float(x) for x in v[1:4]], [float(x) for x in v[4:8]])
    return poses


def camera_frames(mav0, camera):
    """(t_ns, image file) of a camera's data.csv."""
    rows = []
    for line in (mav0 / camera / 'data.csv').read_text().splitlines():
        if line.startswith('#') or not line.strip():
            continue
        t_ns, name = line.split(',')
        rows.append((int(t_ns), mav0 / camera / 'data' / name.strip()))
    return rows


def copy_sensor_yamls(mav0, folder, cameras):
    for sensor in (*cameras, 'imu0'):
        (folder / sensor).mkdir(parents=True)
        shutil.copyfile(mav0 / sensor / 'sensor.yaml', folder / sensor / 'sensor.yaml')


def opencv_matrix(m):
    data = ', '.join(repr(v) for row in m for v in row)
    return f'!!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [{data}]\n'


# ---- the twins ----------------------------------------------------------------------------------

def build_euroc(runner):
    simulate(runner, 'MH_01_easy', '--scene', 'street', '--dynamic', 'low', '--seed', 11)


def build_tumvi(runner):
    # TUM-VI's folders are in the EuRoC layout and its bags have EuRoC's topics; its ground-truth
    # topic /vrpn_client/raw_transform is not one the simulator writes, so the twin bag has none
    # (and its /odometry is not read by --topics tumvi). The cameras are pinhole, not fisheye.
    bag = ('--rosbag', 'dataset-room1_512_16.bag', '--rosbag-layout', 'viode') \
        if runner.rosbag else ()
    simulate(runner, 'dataset-room1_512_16', '--scene', 'indoor', '--dynamic', 'low',
             '--seed', 12, *bag)
    copy_sensor_yamls(runner.work / 'dataset-room1_512_16/mav0', runner.work / 'tumvi_calibration',
                      ('cam0', 'cam1'))


def build_kitti(runner):
    # No command of the tool writes KITTI's layout: this step writes it from the EuRoC twin's
    # stereo images and ground truth (rectified already: both cameras share their orientation and
    # intrinsics and are 0.11 m apart along x).
    runner.ensure('euroc')
    mav0 = runner.work / 'MH_01_easy/mav0'
    sequence = runner.work / 'sequences/00'
    fx, fy, cx, cy, _, _ = sensor_yaml_intrinsics(mav0 / 'cam0/sensor.yaml')
    T_b_c0 = sensor_yaml_matrix(mav0 / 'cam0/sensor.yaml')
    T_b_c1 = sensor_yaml_matrix(mav0 / 'cam1/sensor.yaml')
    T_c0_c1 = matmul(rigid_inverse(T_b_c0), T_b_c1)
    baseline = T_c0_c1[0][3]
    left, right = camera_frames(mav0, 'cam0'), camera_frames(mav0, 'cam1')
    for folder, frames in (('image_0', left), ('image_1', right)):
        (sequence / folder).mkdir(parents=True)
        for i, (_, image) in enumerate(frames):
            shutil.copyfile(image, sequence / folder / f'{i:06d}.png')
    p0 = [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0]
    p1 = [fx, 0, cx, -fx * baseline, 0, fy, cy, 0, 0, 0, 1, 0]
    tr = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]  # Velodyne to camera: unused, as in KITTI's files
    (sequence / 'calib.txt').write_text(''.join(
        f'{label}: ' + ' '.join(f'{float(v):.12e}' for v in values) + '\n'
        for label, values in (('P0', p0), ('P1', p1), ('P2', p0), ('P3', p1), ('Tr', tr))))
    t0 = left[0][0]
    (sequence / 'times.txt').write_text(''.join(f'{(t - t0) * 1e-9:.6e}\n' for t, _ in left))
    ground_truth = euroc_ground_truth(mav0)
    T_w_c = [matmul(pose_matrix(*ground_truth[t]), T_b_c0) for t, _ in left]
    first_inverse = rigid_inverse(T_w_c[0])
    lines = []
    for pose in T_w_c:
        relative = matmul(first_inverse, pose)
        lines.append(' '.join(f'{v:.9e}' for row in relative[:3] for v in row))
    (sequence / 'poses.txt').write_text('\n'.join(lines) + '\n')


def build_viode(runner):
    # A VIODE-layout bag with colour segmentation topics, and VIODE/ laid out as a clone of VIODE's
    # GitHub repository, with its files written from the simulated sequence in VIODE's formats:
    # calibration_files/ (the VINS-Fusion calibration.yaml naming cam0_pinhole.yaml and
    # cam1_pinhole.yaml), segmentation/rgb_ids.txt ("id,r,g,b") and
    # segmentation/vehicle_ids_city_day.txt ("id, name": the twin's vehicles).
    (runner.work / 'city_day').mkdir()
    simulate(runner, 'city_day_simulated', '--scene', 'street', '--dynamic', 'high', '--seed', 13,
             '--semantic-color', '--rosbag', 'city_day/3_high.bag', '--rosbag-layout', 'viode')
    mav0 = runner.work / 'city_day_simulated/mav0'
    calibration = runner.work / 'VIODE/calibration_files'
    segmentation = runner.work / 'VIODE/segmentation'
    calibration.mkdir(parents=True)
    segmentation.mkdir()
    for i in range(2):
        fx, fy, cx, cy, width, height = sensor_yaml_intrinsics(mav0 / f'cam{i}/sensor.yaml')
        (calibration / f'cam{i}_pinhole.yaml').write_text(
            f'%YAML:1.0\n---\nmodel_type: PINHOLE\ncamera_name: camera\nimage_width: {width}\n'
            f'image_height: {height}\ndistortion_parameters:\n   k1: 0.0\n   k2: 0.0\n'
            f'   p1: 0.0\n   p2: 0.0\nprojection_parameters:\n   fx: {fx!r}\n   fy: {fy!r}\n'
            f'   cx: {cx!r}\n   cy: {cy!r}\n')
    imu = mav0 / 'imu0/sensor.yaml'
    T_b_i = sensor_yaml_matrix(imu)  # VINS's body is the IMU
    body_T_cam = [matmul(rigid_inverse(T_b_i), sensor_yaml_matrix(mav0 / f'cam{i}/sensor.yaml'))
                  for i in range(2)]
    (calibration / 'calibration.yaml').write_text(
        '%YAML:1.0\n\nimu: 1\nnum_of_cam: 2\n\nimu_topic: "/imu0"\n'
        'image0_topic: "/cam0/image_raw"\nimage1_topic: "/cam1/image_raw"\n'
        'output_path: "~/output/"\n\ncam0_calib: "cam0_pinhole.yaml"\n'
        'cam1_calib: "cam1_pinhole.yaml"\nimage_width: 752\nimage_height: 480\n\n'
        f'body_T_cam0: {opencv_matrix(body_T_cam[0])}\nbody_T_cam1: {opencv_matrix(body_T_cam[1])}\n'
        f'acc_n: {sensor_yaml_number(imu, "accelerometer_noise_density")!r}\n'
        f'gyr_n: {sensor_yaml_number(imu, "gyroscope_noise_density")!r}\n'
        f'acc_w: {sensor_yaml_number(imu, "accelerometer_random_walk")!r}\n'
        f'gyr_w: {sensor_yaml_number(imu, "gyroscope_random_walk")!r}\ng_norm: 9.81007\n')
    colours = [line for line in (mav0 / 'segmentation_colors.csv').read_text().splitlines()
               if line and not line.startswith('#')]
    (segmentation / 'rgb_ids.txt').write_text('id,r,g,b\n' + '\n'.join(colours) + '\n')
    instances = [line.split(',') for line in (mav0 / 'instances.csv').read_text().splitlines()
                 if line and not line.startswith('#')]
    vehicles = [f'{row[0]}, vehicle_{"dynamic" if row[2] == "1" else "static"}_{k}'
                for k, row in enumerate(r for r in instances if r[1] == 'vehicle')]
    (segmentation / 'vehicle_ids_city_day.txt').write_text('id, name\n' + '\n'.join(vehicles)
                                                             + '\n')


def build_openloris(runner):
    # An OpenLORIS-layout bag (colour camera, accelerometer and gyroscope apart, no ground-truth
    # topic), the calibration folder, and the ground truth as OpenLORIS publishes it: a TUM file
    # (seconds) with header lines.
    simulate(runner, 'market1-1_simulated', '--scene', 'indoor', '--dynamic', 'low', '--seed', 14,
             '--rosbag', 'market1-1.bag', '--rosbag-layout', 'openloris')
    mav0 = runner.work / 'market1-1_simulated/mav0'
    copy_sensor_yamls(mav0, runner.work / 'openloris_calibration', ('cam0',))
    rows = [f'{t // 10**9}.{t % 10**9:09d} {p[0]!r} {p[1]!r} {p[2]!r} {q[1]!r} {q[2]!r} {q[3]!r} '
            f'{q[0]!r}' for t, (p, q) in sorted(euroc_ground_truth(mav0).items())]
    (runner.work / 'market1-1_groundtruth.txt').write_text(
        'scene: market\nseq: 1\n# timestamp tx ty tz qx qy qz qw\n' + '\n'.join(rows) + '\n')


TWINS = {
    'euroc': {'build': build_euroc, 'bag': False,
              'what': 'EuRoC ASL folder MH_01_easy/mav0, 3 s street, simulate'},
    'tumvi': {'build': build_tumvi, 'bag': False,
              'what': 'TUM-VI folder dataset-room1_512_16/mav0 (EuRoC layout), and with bag '
                      'support dataset-room1_512_16.bag (/cam0/image_raw, /cam1/image_raw, '
                      '/imu0) and tumvi_calibration/, 3 s indoor, simulate'},
    'tumvi-bag': {'build': lambda runner: runner.ensure('tumvi'), 'bag': True,
                  'what': 'the tumvi twin\'s bag'},
    'kitti': {'build': build_kitti, 'bag': False,
              'what': 'KITTI odometry folder sequences/00 (image_0, image_1, calib.txt, '
                      'times.txt, poses.txt) written by this test from the euroc twin'},
    'viode': {'build': build_viode, 'bag': True,
              'what': 'VIODE-layout bag city_day/3_high.bag with segmentation topics and VIODE/ '
                      'as its repository holds it (calibration_files/calibration.yaml, '
                      'cam0_pinhole.yaml, cam1_pinhole.yaml; segmentation/rgb_ids.txt, '
                      'vehicle_ids_city_day.txt), 3 s street, simulate'},
    'openloris': {'build': build_openloris, 'bag': True,
                  'what': 'OpenLORIS-layout bag market1-1.bag, openloris_calibration/ and '
                          'market1-1_groundtruth.txt, 3 s indoor, simulate'},
}


# ---- the page -----------------------------------------------------------------------------------

def fenced_blocks(page):
    """(first line of the content, language, content, marker match or None) of every block."""
    lines = Path(page).read_text().splitlines()
    blocks = []
    i = 0
    while i < len(lines):
        fence = re.match(r'\s*```(\w*)\s*$', lines[i])
        if not fence:
            i += 1
            continue
        indent = len(lines[i]) - len(lines[i].lstrip())
        end = i + 1
        while end < len(lines) and lines[end].strip() != '```':
            end += 1
        if end == len(lines):
            sys.exit(f'{page}:{i + 1}: the block is not closed')
        before = lines[i - 1].strip() if i > 0 else ''
        marker = MARKER.match(before)
        if before.startswith('<!-- docs-test') and not marker:
            sys.exit(f'{page}:{i}: a marker reads <!-- docs-test -->, <!-- docs-test: TWIN --> or '
                     '<!-- docs-test: TWIN writes FILE from BASE -->, with an optional "; note"')
        content = '\n'.join(line[indent:] for line in lines[i + 1:end])
        blocks.append((i + 2, fence.group(1), content, marker))
        i = end + 1
    for n, line in enumerate(lines):
        if line.strip().startswith('<!-- docs-test') and not any(
                b[0] == n + 3 for b in blocks):
            sys.exit(f'{page}:{n + 1}: a docs-test marker must be followed directly by a fence')
    return blocks


def merge_yaml_sections(base_text, section_text):
    """BASE with its top-level sections that SECTION has replaced by SECTION's."""
    keys = set(re.findall(r'^([\w-]+):', section_text, re.M))
    kept, dropping = [], False
    for line in base_text.splitlines():
        top = re.match(r'^([\w-]+):', line)
        if top:
            dropping = top.group(1) in keys
        elif line and not line[0].isspace():
            dropping = False  # a top-level comment
        if not dropping:
            kept.append(line)
    return '\n'.join(kept).rstrip('\n') + '\n' + section_text.rstrip('\n') + '\n'


def run_block(runner, page, line, language, content, marker):
    """0 when the block ran, 1 when it failed, SKIPPED when this build cannot run it."""
    twin = marker.group('twin')
    if twin is not None and twin not in TWINS:
        sys.exit(f'{page}:{line}: unknown twin {twin!r} (twins: {", ".join(TWINS)})')
    needs_bag = (twin is not None and TWINS[twin]['bag']) or 'rosbag' in content
    label = f'{page}:{line}' + (f' (twin {twin})' if twin else '') + \
        (f' [{marker.group("note")}]' if marker.group('note') else '')
    if needs_bag and not runner.rosbag:
        print(f'-- {label}: skipped (this build has no ROS bag support)\n{content}')
        return SKIPPED
    if twin is not None:
        runner.ensure(twin)
    if marker.group('file'):
        if language != 'yaml':
            sys.exit(f'{page}:{line}: "writes FILE from BASE" marks a ```yaml block')
        base = (runner.repo / marker.group('base')).read_text()
        target = runner.work / marker.group('file')
        target.write_text(merge_yaml_sections(base, runner.substitute(content)))
        print(f'-- {label}: wrote {marker.group("file")} = {marker.group("base")} with\n{content}')
        return 0
    if language != 'sh':
        sys.exit(f'{page}:{line}: a marked block is a ```sh block (or a ```yaml block that '
                 'writes a file)')
    print(f'-- {label}\n{content}', flush=True)
    started = time.monotonic()
    result = subprocess.run(['bash', '-euo', 'pipefail', '-c', runner.substitute(content)],
                            cwd=runner.work, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    if result.returncode != 0:
        print(result.stdout[-4000:])
        print(f'FAILED: the block at {page}:{line} exited with {result.returncode}')
        return 1
    print(f'   ok ({time.monotonic() - started:.1f} s)', flush=True)
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('page')
    parser.add_argument('--superdyna', required=True)
    parser.add_argument('--repo', required=True)
    parser.add_argument('--work', required=True)
    parser.add_argument('--no-rosbag', action='store_true')
    args = parser.parse_args()
    if not Path(args.superdyna).is_file():
        print(f'skipped: the tool {args.superdyna} is not built')
        return SKIPPED
    blocks = fenced_blocks(args.page)
    marked = [b for b in blocks if b[3]]
    unmarked = [b for b in blocks if not b[3] and b[1] == 'sh']
    if not marked:
        sys.exit(f'{args.page}: no block is marked with <!-- docs-test -->')
    runner = Runner(args)
    if runner.work.exists():
        shutil.rmtree(runner.work)
    runner.work.mkdir(parents=True)
    started = time.monotonic()
    skipped = 0
    for line, language, content, marker in marked:
        status = run_block(runner, args.page, line, language, content, marker)
        if status == 1:
            return 1
        skipped += status == SKIPPED
    print(f'{len(marked) - skipped} marked blocks of {args.page} ran in '
          f'{time.monotonic() - started:.0f} s (twins: {", ".join(sorted(runner.built)) or "none"})'
          + (f', {skipped} skipped' if skipped else ''))
    print(f'{len(unmarked)} ```sh blocks of the page are not marked (not run)'
          + (': lines ' + ', '.join(str(b[0]) for b in unmarked) if unmarked else ''))
    if skipped:
        print(f'skipped: {skipped} marked blocks need ROS bag support, which this build lacks')
        return SKIPPED
    return 0


if __name__ == '__main__':
    sys.exit(main())
