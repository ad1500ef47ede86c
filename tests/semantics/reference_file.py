"""The checked-in output of a numpy reference script (yolo_reference.py, sam_reference.py):
written beside the script, or with --check recomputed and compared with the checked-in file."""


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
