#!/usr/bin/env python3
"""Plain numpy reference of the YOLOv8-seg decoding steps (src/semantics/yolo_decoder.cc).

Builds fixed random network outputs for a small configuration, decodes them with the same steps
as the C++ decoder (letterbox geometry, detections, class-aware NMS, masks, instances), and writes
inputs and expected results to yolo_reference_data.txt, which semantics_test reads.

  yolo_reference.py            write yolo_reference_data.txt beside this script
  yolo_reference.py --check    recompute and fail unless the checked-in file is reproduced
"""
import os
import sys

import numpy as np

from reference_file import iou, write_or_check

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "yolo_reference_data.txt")

LABELS = ["person", "car", "dog", "chair"]
WANTED_CLASSES = {"person": 2, "car": 1}  # default taxonomy: pedestrian 2, vehicle 1
IMAGE_W, IMAGE_H = 80, 48
INPUT_W, INPUT_H = 64, 64
MASKS, PROTO_H, PROTO_W = 32, 16, 16
ANCHORS = 40
SCORE_THRESHOLD, NMS_IOU, MASK_THRESHOLD, MIN_AREA, MAX_DETECTIONS = 0.25, 0.45, 0.5, 20, 100


def make_inputs():
    rng = np.random.default_rng(20261201)
    classes = len(LABELS)
    out = np.zeros((4 + classes + MASKS, ANCHORS), dtype=np.float32)
    out[0] = rng.uniform(0, INPUT_W, ANCHORS)
    out[1] = rng.uniform(12, 52, ANCHORS)
    out[2] = rng.uniform(6, 40, ANCHORS)
    out[3] = rng.uniform(6, 30, ANCHORS)
    out[4:4 + classes] = rng.uniform(0, 0.2, (classes, ANCHORS))
    out[4 + classes:] = rng.normal(0, 1, (MASKS, ANCHORS))
    # Planted detections: (anchor, class, score, cx, cy, w, h).
    planted = [
        (3, 1, 0.90, 20.0, 30.0, 24.0, 16.0),  # a car
        (4, 1, 0.80, 21.0, 31.0, 24.0, 16.0),  # the same car again: suppressed by NMS
        (5, 0, 0.70, 24.0, 30.0, 12.0, 20.0),  # a person over the car: another class, kept
        (6, 2, 0.95, 45.0, 25.0, 20.0, 14.0),  # a dog: background in the default taxonomy
        (7, 1, 0.60, 50.0, 45.0, 3.0, 3.0),    # a tiny car: below the minimum area
        (8, 1, 0.55, 48.0, 40.0, 28.0, 14.0),  # a second car
        (9, 0, 0.26, 10.0, 20.0, 10.0, 18.0),  # a person just above the score threshold
        (10, 0, 0.25, 60.0, 20.0, 8.0, 8.0),   # exactly at the threshold: not a detection
    ]
    for anchor, cls, score, cx, cy, w, h in planted:
        out[0:4, anchor] = (cx, cy, w, h)
        out[4 + cls, anchor] = score
    protos = rng.normal(0, 1, (MASKS, PROTO_H, PROTO_W)).astype(np.float32)
    return out, protos


def letterbox():
    scale = min(INPUT_W / IMAGE_W, INPUT_H / IMAGE_H)
    scaled_w, scaled_h = round(IMAGE_W * scale), round(IMAGE_H * scale)
    left = round((INPUT_W - scaled_w) / 2 - 0.1)
    top = round((INPUT_H - scaled_h) / 2 - 0.1)
    return scale, left, top, scaled_w, scaled_h


def decode(out, protos):
    classes = len(LABELS)
    scores = out[4:4 + classes]
    best = np.argmax(scores, axis=0)
    best_score = scores[best, np.arange(ANCHORS)]
    wanted = np.array([label in WANTED_CLASSES for label in LABELS])
    keep = (best_score > SCORE_THRESHOLD) & wanted[best]
    anchors = np.nonzero(keep)[0]
    boxes = {}
    for a in anchors:
        cx, cy, w, h = (float(v) for v in out[0:4, a])
        boxes[a] = (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
    order = anchors[np.argsort(-best_score[anchors], kind="stable")]
    kept = []
    for a in order:
        if len(kept) >= MAX_DETECTIONS:
            break
        if all(best[k] != best[a] or iou(boxes[k], boxes[a]) <= NMS_IOU for k in kept):
            kept.append(a)

    scale, left, top, _, _ = letterbox()
    stride_x, stride_y = INPUT_W / PROTO_W, INPUT_H / PROTO_H
    u = (np.arange(IMAGE_W) + 0.5) * scale + left
    v = (np.arange(IMAGE_H) + 0.5) * scale + top
    px, py = u / stride_x - 0.5, v / stride_y - 0.5
    x0, y0 = np.floor(px), np.floor(py)
    ax, ay = px - x0, py - y0
    xi0 = np.clip(x0, 0, PROTO_W - 1).astype(int)
    xi1 = np.clip(x0 + 1, 0, PROTO_W - 1).astype(int)
    yi0 = np.clip(y0, 0, PROTO_H - 1).astype(int)
    yi1 = np.clip(y0 + 1, 0, PROTO_H - 1).astype(int)

    ids = np.zeros((IMAGE_H, IMAGE_W), dtype=np.int64)
    instances = []
    flat = protos.reshape(MASKS, -1).astype(np.float64)
    for a in kept:
        coefficients = out[4 + classes:, a].astype(np.float64)
        prob = (1.0 / (1.0 + np.exp(-(coefficients @ flat)))).reshape(PROTO_H, PROTO_W)
        top_row = (1 - ax)[None, :] * prob[yi0][:, xi0] + ax[None, :] * prob[yi0][:, xi1]
        bottom_row = (1 - ax)[None, :] * prob[yi1][:, xi0] + ax[None, :] * prob[yi1][:, xi1]
        sampled = (1 - ay)[:, None] * top_row + ay[:, None] * bottom_row
        x1, y1, x2, y2 = boxes[a]
        inside = ((v >= y1) & (v < y2))[:, None] & ((u >= x1) & (u < x2))[None, :]
        mask = inside & (sampled > MASK_THRESHOLD)
        taken = mask & (ids == 0)
        area = int(taken.sum())
        if area < MIN_AREA:
            continue
        instance_id = len(instances) + 1
        ids[taken] = instance_id
        to_x = lambda value: min(max((value - left) / scale, 0.0), float(IMAGE_W))
        to_y = lambda value: min(max((value - top) / scale, 0.0), float(IMAGE_H))
        bx0, by0 = int(np.floor(to_x(x1))), int(np.floor(to_y(y1)))
        bx1, by1 = int(np.ceil(to_x(x2))), int(np.ceil(to_y(y2)))
        label = LABELS[best[a]]
        instances.append((instance_id, label, WANTED_CLASSES[label], best_score[a], bx0, by0,
                          max(0, bx1 - bx0), max(0, by1 - by0), area))
    return instances, ids


def floats(values):
    return " ".join(format(float(np.float32(x)), ".9g") for x in np.asarray(values).ravel())


def render():
    out, protos = make_inputs()
    instances, ids = decode(out, protos)
    scale, left, top, scaled_w, scaled_h = letterbox()
    lines = ["# Generated by yolo_reference.py (numpy reference of the YOLOv8-seg decoding).",
             f"image {IMAGE_W} {IMAGE_H}", f"input {INPUT_W} {INPUT_H}",
             f"letterbox {scale!r} {left} {top} {scaled_w} {scaled_h}",
             "labels " + " ".join(LABELS),
             f"options {SCORE_THRESHOLD!r} {NMS_IOU!r} {MASK_THRESHOLD!r} {MIN_AREA} "
             f"{MAX_DETECTIONS}",
             f"output0 {out.shape[0]} {out.shape[1]}", floats(out),
             f"protos {MASKS} {PROTO_H} {PROTO_W}", floats(protos),
             f"instances {len(instances)}"]
    for instance_id, label, cls, score, x, y, w, h, area in instances:
        lines.append(f"{instance_id} {label} {cls} {float(score)!r} {x} {y} {w} {h} {area}")
    lines.append("ids " + " ".join(str(int(i)) for i in ids.ravel()))
    return "\n".join(lines) + "\n"


def main():
    return write_or_check(DATA, render(), sys.argv)


if __name__ == "__main__":
    sys.exit(main())
