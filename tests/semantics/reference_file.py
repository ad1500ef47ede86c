"""Shared by the numpy reference scripts (yolo_reference.py, sam_reference.py): the IoU their NMS
uses, and their checked-in output, written beside the script or with --check recomputed and
compared with the checked-in file."""


def iou(a, b):
    """Intersection over union of two (x1, y1, x2, y2) boxes; 0 when both are empty."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    inter = max(0.0, w) * max(0.0, h)
    area = lambda r: max(0.0, r[2] - r[0]) * max(0.0, r[3] - r[1])
    union = area(a) + area(b) - inter
    return inter / union if union > 0 else 0.0


def write_or_check(path, text, argv):
    """Writes `text` to `path`, or with --check in argv fails (returns 1) unless the file holds it."""
    if len(argv) > 1 and argv[1] == "--check":
        with open(path) as f:
            if f.read() != text:
                print(f"{path} differs from what the reference computes")
                return 1
        print(f"{path} reproduced")
        return 0
    with open(path, "w") as f:
        f.write(text)
    print(f"wrote {path}")
    return 0
