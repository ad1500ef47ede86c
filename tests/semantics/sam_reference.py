#!/usr/bin/env python3
"""Plain numpy reference of the sam backend's steps (src/semantics/yolox_decoder.cc, sam_prompt.cc,
sam_segmenter.cc's samInstances), on fixed inputs:

  - YOLOX: the network input of an image at scale 1 (BGR kept, 0..255, grey 114 padding at the
    bottom), and the detections of a fixed random output tensor (grid decoding of strides 8, 16
    and 32, objectness x class probability, class-aware NMS, boxes divided by the letterbox scale);
  - SAM: the encoder input of an image whose longest side is 1024 (RGB, SAM's mean and standard
    deviation, zero padding), box and point prompts, and masks from fixed logits made into
    instances best score first.

Writes inputs and expected results to sam_reference_data.txt, which semantics_test reads.

  sam_reference.py            write sam_reference_data.txt beside this script
  sam_reference.py --check    recompute and fail unless the checked-in file is reproduced
"""
import math
import os
import sys

import numpy as np

from reference_file import iou, write_or_check

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "sam_reference_data.txt")

CLASSES = 80
PERSON, CAR, DOG = 0, 2, 16  # COCO indices; the default taxonomy wants person (2) and car (1)
CLASS_OF = {PERSON: 2, CAR: 1}
INPUT_W, INPUT_H = 64, 64
STRIDES = (8, 16, 32)
DETECT_IMAGE_W, DETECT_IMAGE_H = 80, 56  # letterbox scale 0.8
INPUT_IMAGE_W, INPUT_IMAGE_H = 64, 40    # letterbox scale 1: the input test needs no resize
SCORE_THRESHOLD, NMS_IOU, MAX_DETECTIONS, MIN_AREA = 0.3, 0.45, 20, 20
SAM_IMAGE_W, SAM_IMAGE_H = 1024, 600
SAM_MEAN = np.array([123.675, 116.28, 103.53], dtype=np.float32)
SAM_STD = np.array([58.395, 57.12, 57.375], dtype=np.float32)
PROMPT_IMAGE_W, PROMPT_IMAGE_H = 752, 480
PROMPT_BOX = (100.25, 50.5, 300.75, 200.0)  # x1, y1, x2, y2
PROMPT_POINTS = ((10.0, 20.0, 1), (30.5, 40.25, 0))
SAMPLES = ((0, 0, 0), (0, 599, 1023), (1, 123, 456), (2, 300, 700), (0, 599, 0), (1, 600, 0),
           (2, 1023, 1023), (0, 37, 911), (1, 412, 5), (2, 599, 1023))


def anchor_cells():
    cells = []
    for stride in STRIDES:
        cols, rows = INPUT_W // stride, INPUT_H // stride
        cells += [(stride, i % cols, i // cols) for i in range(rows * cols)]
    return cells


def make_yolox_output(rng):
    anchors = len(anchor_cells())
    out = np.zeros((anchors, 5 + CLASSES), dtype=np.float32)
    out[:, 0:2] = rng.uniform(-0.5, 1.5, (anchors, 2))
    out[:, 2:4] = rng.uniform(-1.0, 1.0, (anchors, 2))
    out[:, 4] = rng.uniform(0.0, 0.5, anchors)
    out[:, 5:] = rng.uniform(0.0, 0.5, (anchors, CLASSES))  # scores below 0.25
    # Planted: (anchor, class, objectness, probability, dx, dy, log w, log h).
    planted = [
        (10, CAR, 0.95, 0.9, 0.5, 0.5, 0.3, 0.0),     # a car (stride 8)
        (11, CAR, 0.90, 0.8, -0.45, 0.45, 0.35, 0.05),  # the same car again: suppressed
        (12, PERSON, 0.9, 0.7, 0.1, 0.6, -0.2, 0.5),  # a person over the car: kept
        (70, DOG, 0.99, 0.99, 0.5, 0.5, 0.0, 0.0),    # a dog: background in the taxonomy
        (72, CAR, 0.9, 0.6, 0.4, 0.5, 0.2, -0.3),     # a second car (stride 16)
        (81, PERSON, 1.0, 0.31, 0.5, 0.5, 0.4, 0.8),  # just above the threshold (stride 32)
        (82, CAR, 1.0, 0.29, 0.5, 0.5, 0.0, 0.0),     # just below it
        (20, PERSON, 0.9, 0.9, 0.5, 0.5, -1.2, -1.2),  # a tiny person: below the minimum area
    ]
    for anchor, cls, obj, prob, dx, dy, lw, lh in planted:
        out[anchor, 0:4] = (dx, dy, lw, lh)
        out[anchor, 4] = obj
        out[anchor, 5:] = np.minimum(out[anchor, 5:], 0.2)
        out[anchor, 5 + cls] = prob
    return out


def yolox_detections(out):
    """(class, score, x1, y1, x2, y2) in image pixels, best first."""
    scale = min(INPUT_W / DETECT_IMAGE_W, INPUT_H / DETECT_IMAGE_H)
    candidates = []
    for a, (stride, col, row) in enumerate(anchor_cells()):
        probs = out[a, 5:]
        best = int(np.argmax(probs))
        score = out[a, 4] * probs[best]  # float32 product, as the decoder
        if not (float(score) > SCORE_THRESHOLD) or best not in CLASS_OF:
            continue
        cx = (float(out[a, 0]) + col) * stride
        cy = (float(out[a, 1]) + row) * stride
        w = math.exp(float(out[a, 2])) * stride
        h = math.exp(float(out[a, 3])) * stride
        candidates.append((a, best, score, (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)))
    candidates.sort(key=lambda c: (-float(c[2]), c[0]))
    kept = []
    for c in candidates:
        if len(kept) >= MAX_DETECTIONS:
            break
        if all(k[1] != c[1] or iou(k[3], c[3]) <= NMS_IOU for k in kept):
            kept.append(c)
    return [(cls, score, *(v / scale for v in box)) for _, cls, score, box in kept]


def yolox_input():
    """The test image (BGR, from a formula the C++ test repeats) as the network input."""
    r, c = np.mgrid[0:INPUT_IMAGE_H, 0:INPUT_IMAGE_W]
    bgr = np.stack([(3 * r + 5 * c) % 256, (7 * r + 2 * c + 11) % 256, (r * c) % 256], axis=-1)
    canvas = np.full((INPUT_H, INPUT_W, 3), 114, dtype=np.float32)
    canvas[:INPUT_IMAGE_H, :INPUT_IMAGE_W] = bgr
    return canvas.transpose(2, 0, 1)


def sam_input():
    r, c = np.mgrid[0:SAM_IMAGE_H, 0:SAM_IMAGE_W]
    bgr = np.stack([(3 * r + 5 * c) % 256, (7 * r + 2 * c + 11) % 256, (r * c) % 256], axis=-1)
    rgb = bgr[:, :, ::-1].astype(np.float32)
    planes = np.zeros((3, 1024, 1024), dtype=np.float32)
    planes[:, :SAM_IMAGE_H, :SAM_IMAGE_W] = ((rgb - SAM_MEAN) / SAM_STD).transpose(2, 0, 1)
    return planes


def prompts():
    scale = 1024 / max(PROMPT_IMAGE_W, PROMPT_IMAGE_H)
    x1, y1, x2, y2 = PROMPT_BOX
    box = ([x1 * scale, y1 * scale, x2 * scale, y2 * scale], [2, 3])
    coords, labels = [], []
    for x, y, on in PROMPT_POINTS:
        coords += [x * scale, y * scale]
        labels.append(on)
    points = (coords + [0.0, 0.0], labels + [-1])
    scaled = (math.floor(PROMPT_IMAGE_W * scale + 0.5), math.floor(PROMPT_IMAGE_H * scale + 0.5))
    return scale, scaled, box, points


def instances_of(detections, logits):
    ids = np.zeros((DETECT_IMAGE_H, DETECT_IMAGE_W), dtype=np.int64)
    instances = []
    for (cls, score, x1, y1, x2, y2), logit in zip(detections, logits):
        taken = (logit > 0.0) & (ids == 0)
        area = int(taken.sum())
        if area < MIN_AREA:
            continue
        instance_id = len(instances) + 1
        ids[taken] = instance_id
        clamp = lambda v, n: min(max(v, 0.0), float(n))
        bx0 = int(math.floor(clamp(x1, DETECT_IMAGE_W)))
        by0 = int(math.floor(clamp(y1, DETECT_IMAGE_H)))
        bx1 = int(math.ceil(clamp(x2, DETECT_IMAGE_W)))
        by1 = int(math.ceil(clamp(y2, DETECT_IMAGE_H)))
        instances.append((instance_id, cls, CLASS_OF[cls], float(score), bx0, by0,
                          max(0, bx1 - bx0), max(0, by1 - by0), area))
    return instances, ids


def make_logits(rng, detections):
    """Per detection: noise, raised inside its box and lowered outside (overlaps between them)."""
    r, c = np.mgrid[0:DETECT_IMAGE_H, 0:DETECT_IMAGE_W]
    logits = []
    for _, _, x1, y1, x2, y2 in detections:
        inside = (c + 0.5 >= x1) & (c + 0.5 < x2) & (r + 0.5 >= y1) & (r + 0.5 < y2)
        noise = rng.normal(0.0, 1.0, (DETECT_IMAGE_H, DETECT_IMAGE_W))
        logits.append((noise + np.where(inside, 1.5, -3.5)).astype(np.float32))
    return logits


def floats(values):
    return " ".join(format(float(np.float32(x)), ".9g") for x in np.asarray(values).ravel())


def exact(values):
    return " ".join(repr(float(x)) for x in values)


def render():
    rng = np.random.default_rng(20261205)
    out = make_yolox_output(rng)
    detections = yolox_detections(out)
    logits = make_logits(rng, detections)
    instances, ids = instances_of(detections, logits)
    encoder = sam_input()
    scale, scaled, box, points = prompts()
    network_input = yolox_input()
    lines = ["# Generated by sam_reference.py (numpy reference of the sam backend's steps).",
             f"yolox_input {INPUT_IMAGE_W} {INPUT_IMAGE_H} {INPUT_W} {INPUT_H}",
             f"yolox_input_sums {exact(network_input.reshape(3, -1).sum(axis=1, dtype=np.float64))}",
             f"yolox_input_samples {floats([network_input[k, r, c] for k, r, c in ((0, 0, 0), (2, 39, 63), (1, 40, 0), (0, 63, 63), (1, 17, 29))])}",
             f"detect_image {DETECT_IMAGE_W} {DETECT_IMAGE_H}",
             f"options {SCORE_THRESHOLD!r} {NMS_IOU!r} {MAX_DETECTIONS} {MIN_AREA}",
             f"output {out.shape[0]} {out.shape[1]}", floats(out),
             f"detections {len(detections)}"]
    for cls, score, x1, y1, x2, y2 in detections:
        lines.append(f"{cls} {float(score)!r} {exact((x1, y1, x2, y2))}")
    lines.append("logits")
    lines += [floats(logit) for logit in logits]
    lines.append(f"instances {len(instances)}")
    for instance_id, cls, class_id, score, x, y, w, h, area in instances:
        lines.append(f"{instance_id} {cls} {class_id} {score!r} {x} {y} {w} {h} {area}")
    lines.append("ids " + " ".join(str(int(i)) for i in ids.ravel()))
    lines.append(f"sam_image {SAM_IMAGE_W} {SAM_IMAGE_H}")
    lines.append(f"sam_input_sums {exact(encoder.reshape(3, -1).sum(axis=1, dtype=np.float64))}")
    lines.append("sam_input_samples " + " ".join(f"{k} {r} {c} {format(float(encoder[k, r, c]), '.9g')}" for k, r, c in SAMPLES))
    lines.append(f"prompt_image {PROMPT_IMAGE_W} {PROMPT_IMAGE_H} {scale!r} {scaled[0]} {scaled[1]}")
    lines.append(f"box {exact(PROMPT_BOX)} -> {floats(box[0])} labels {floats(box[1])}")
    lines.append("points " + " ".join(f"{x!r} {y!r} {on}" for x, y, on in PROMPT_POINTS) +
                 f" -> {floats(points[0])} labels {floats(points[1])}")
    return "\n".join(lines) + "\n"


def main():
    return write_or_check(DATA, render(), sys.argv)


if __name__ == "__main__":
    sys.exit(main())
