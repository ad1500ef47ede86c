#!/usr/bin/env python3
"""Small ONNX graphs with the output contract of torchvision's Mask R-CNN export, and a plain
numpy reference of their decoding, for tests/semantics/maskrcnn_segmenter_test.cc.

    maskrcnn_contract_model.py OUT_DIR

writes into OUT_DIR:
  image_masks.onnx   input [3, H, W]; masks [N, 1, H, W] = soft masks x the image's red channel
  box_masks.onnx     input [1, 3, H, W]; masks [N, 1, 14, 14] = soft masks x max(red channel)
  no_masks.onnx      the first without its masks output (a wrong contract)
  image_masks.txt, box_masks.txt   the segmentation the decoding must give: one line per
                     instance "instance id label class score x y w h area", then "ids" and H rows of
                     W instance ids
Boxes, labels and scores are constants (Constant nodes); the masks depend on the input, so the
graph really runs on the test image. The image (B, G, R bytes) is image() below; the C++ test
builds the same one. Needs Debian's python3-onnx and python3-numpy.
"""
import os
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

H, W = 48, 64
BOX_MASK = 14

# torchvision's COCO category list (index = label id), as torchvision's detection models use.
CATEGORIES = [
    "__background__", "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train",
    "truck", "boat", "traffic light", "fire hydrant", "N/A", "stop sign", "parking meter",
    "bench", "bird", "cat", "dog", "horse", "sheep", "cow", "elephant", "bear", "zebra",
    "giraffe", "N/A", "backpack", "umbrella", "N/A", "N/A", "handbag", "tie", "suitcase",
    "frisbee", "skis", "snowboard", "sports ball", "kite", "baseball bat", "baseball glove",
    "skateboard", "surfboard", "tennis racket", "bottle", "N/A", "wine glass", "cup", "fork",
    "knife", "spoon", "bowl", "banana", "apple", "sandwich", "orange", "broccoli", "carrot",
    "hot dog", "pizza", "donut", "cake", "chair", "couch", "potted plant", "bed", "N/A",
    "dining table", "N/A", "N/A", "toilet", "N/A", "tv", "laptop", "mouse", "remote",
    "keyboard", "cell phone", "microwave", "oven", "toaster", "sink", "refrigerator", "N/A",
    "book", "clock", "vase", "scissors", "teddy bear", "hair drier", "toothbrush"]
# The default taxonomy (semantics.pedestrian_labels / vehicle_labels): class ids of
# sensors::kInstanceClass* (vehicle 1, pedestrian 2); other labels are background.
CLASSES = {"person": 2, "bicycle": 1, "car": 1, "motorcycle": 1, "bus": 1, "train": 1,
           "truck": 1}
SCORE_THRESHOLD = 0.5
MASK_THRESHOLD = 0.5
MIN_AREA = 100

# (label id, score, box x1 y1 x2 y2); deliberately not in score order.
DETECTIONS = [
    (1, 0.90, (5.3, 4.7, 30.2, 40.5)),     # person, overlapped by the car
    (3, 0.95, (20.0, 10.25, 60.6, 35.0)),  # car, best wanted score
    (62, 0.99, (0.0, 0.0, 20.0, 20.0)),    # chair: background in the taxonomy
    (8, 0.30, (2.0, 30.0, 40.0, 47.0)),    # truck below the score threshold
    (6, 0.70, (50.0, 38.0, 58.0, 46.0)),   # bus with a tiny mask: below the minimum area
    (12, 0.80, (10.0, 10.0, 40.0, 40.0)),  # "N/A": no category
    (4, 0.60, (36.5, 6.0, 63.9, 30.0)),    # motorcycle, partly under the dark red block
    (1, 0.55, (0.0, 28.0, 22.0, 47.9)),    # second person, partly overlapped by the first
]


def image():
    """The test image as H x W x 3 bytes in OpenCV's B, G, R order."""
    y, x = np.mgrid[0:H, 0:W]
    bgr = np.zeros((H, W, 3), np.uint8)
    bgr[..., 0] = (3 * x + 5 * y) % 256
    bgr[..., 1] = (7 * x + y) % 256
    bgr[..., 2] = 230
    bgr[10:30, 40:52, 2] = 100  # a dark red block that weakens the masks there
    return bgr


def soft_masks(rng, height, width, boxes):
    """Soft masks [N, 1, height, width]: high on an ellipse inside each box (given in the grid's
    own coordinates), low elsewhere, with noise."""
    masks = np.zeros((len(boxes), 1, height, width), np.float32)
    y, x = np.mgrid[0:height, 0:width] + 0.5
    for n, (x1, y1, x2, y2) in enumerate(boxes):
        cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
        rx, ry = max((x2 - x1) / 2, 0.5), max((y2 - y1) / 2, 0.5)
        inside = ((x - cx) / rx) ** 2 + ((y - cy) / ry) ** 2 <= 1.0
        noise = rng.uniform(0.0, 0.35, size=(height, width))
        masks[n, 0] = np.where(inside, 1.0 - noise, noise).astype(np.float32)
    return masks


def image_resolution_masks(rng):
    boxes = [box for _, _, box in DETECTIONS]
    masks = soft_masks(rng, H, W, boxes)
    masks[4, 0] = 0.0  # the bus: a 6 x 5 patch only
    masks[4, 0, 39:44, 51:57] = 0.9
    return masks


def box_resolution_masks(rng):
    return soft_masks(rng, BOX_MASK, BOX_MASK, [(0, 0, BOX_MASK, BOX_MASK)] * len(DETECTIONS))


def constant(name, array):
    return helper.make_node("Constant", [], [name], value=numpy_helper.from_array(array, name))


def build_model(masks, batched, with_masks):
    """Constant boxes / labels / scores; masks = constant soft masks x the red channel (image
    resolution) or x the red channel's maximum (box resolution)."""
    nodes = [
        constant("boxes", np.array([d[2] for d in DETECTIONS], np.float32)),
        constant("labels", np.array([d[0] for d in DETECTIONS], np.int64)),
        constant("scores", np.array([d[1] for d in DETECTIONS], np.float32)),
        constant("soft", masks),
        constant("starts", np.array([0], np.int64)),
        constant("ends", np.array([1], np.int64)),
        constant("axis", np.array([1 if batched else 0], np.int64)),
    ]
    # The red channel [1, H, W] (or [1, 1, H, W]).
    nodes.append(helper.make_node("Slice", ["images", "starts", "ends", "axis"], ["red"]))
    image_resolution = masks.shape[2] == H
    if image_resolution:
        if batched:
            nodes.append(helper.make_node("Identity", ["red"], ["factor"]))
        else:
            nodes.append(constant("unsqueeze_axes", np.array([0], np.int64)))
            nodes.append(helper.make_node("Unsqueeze", ["red", "unsqueeze_axes"], ["factor"]))
    else:
        nodes.append(helper.make_node("ReduceMax", ["red"], ["factor"], keepdims=0))
    nodes.append(helper.make_node("Mul", ["soft", "factor"], ["masks"]))

    dims = ["height", "width"]
    input_shape = ([1] if batched else []) + [3] + dims
    outputs = [helper.make_tensor_value_info("boxes", TensorProto.FLOAT, ["n", 4]),
               helper.make_tensor_value_info("labels", TensorProto.INT64, ["n"]),
               helper.make_tensor_value_info("scores", TensorProto.FLOAT, ["n"])]
    if with_masks:
        outputs.append(helper.make_tensor_value_info("masks", TensorProto.FLOAT,
                                                     ["n", 1, "mask_h", "mask_w"]))
    else:
        outputs.append(helper.make_tensor_value_info("mask_probabilities", TensorProto.FLOAT,
                                                     ["n", 1, "mask_h", "mask_w"]))
        nodes[-1].output[0] = "mask_probabilities"
    graph = helper.make_graph(
        nodes, "maskrcnn_contract",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, input_shape)], outputs)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)],
                              producer_name="superdyna tests")
    model.ir_version = 7
    onnx.checker.check_model(model)
    return model


# ---- the reference decoding ------------------------------------------------------------------


def network_masks(masks, rgb):
    """What the graph computes, in float32 as ONNX Runtime does."""
    red = rgb[..., 0]
    if masks.shape[2] == H:
        return masks * red[None, None]
    return masks * red.max()


def pixel_box(x1, y1, x2, y2):
    cx1, cx2 = (min(max(v, 0.0), W) for v in (x1, x2))
    cy1, cy2 = (min(max(v, 0.0), H) for v in (y1, y2))
    x0, y0 = int(np.floor(cx1)), int(np.floor(cy1))
    return x0, y0, max(0, int(np.ceil(cx2)) - x0), max(0, int(np.ceil(cy2)) - y0)


def bilinear(grid, x, y):
    h, w = grid.shape
    fx0, fy0 = np.floor(x), np.floor(y)
    ax, ay = x - fx0, y - fy0
    x0, x1 = (int(min(max(v, 0), w - 1)) for v in (fx0, fx0 + 1))
    y0, y1 = (int(min(max(v, 0), h - 1)) for v in (fy0, fy0 + 1))
    return ((1 - ay) * ((1 - ax) * grid[y0, x0] + ax * grid[y0, x1]) +
            ay * ((1 - ax) * grid[y1, x0] + ax * grid[y1, x1]))


def binary_mask(soft, box):
    """The pixels of one detection's mask in the image."""
    if soft.shape == (H, W):
        return soft > MASK_THRESHOLD
    x1, y1, x2, y2 = (float(np.float32(v)) for v in box)
    mask = np.zeros((H, W), bool)
    grid = soft.astype(np.float64)
    gh, gw = grid.shape
    for y in range(H):
        v = y + 0.5
        if not (y1 <= v < y2):
            continue
        for x in range(W):
            u = x + 0.5
            if not (x1 <= u < x2):
                continue
            p = bilinear(grid, (u - x1) / (x2 - x1) * gw - 0.5, (v - y1) / (y2 - y1) * gh - 0.5)
            mask[y, x] = p > MASK_THRESHOLD
    return mask


def reference(masks):
    rgb = image()[..., ::-1].astype(np.float32) / np.float32(255.0)
    soft = network_masks(masks, rgb)
    order = [n for n, (label, score, _) in enumerate(DETECTIONS)
             if np.float32(score) > SCORE_THRESHOLD and CATEGORIES[label] in CLASSES]
    order.sort(key=lambda n: -np.float32(DETECTIONS[n][1]))
    ids = np.zeros((H, W), np.uint16)
    instances = []
    for n in order:
        label, score, box = DETECTIONS[n]
        taken = binary_mask(soft[n, 0], box) & (ids == 0)
        area = int(taken.sum())
        if area < MIN_AREA:
            continue
        instance_id = len(instances) + 1
        ids[taken] = instance_id
        name = CATEGORIES[label]
        instances.append((instance_id, name, CLASSES[name], np.float32(score),
                          pixel_box(*(float(np.float32(v)) for v in box)), area))
    return instances, ids


def write_expected(path, instances, ids):
    with open(path, "w") as out:
        for instance_id, name, class_id, score, (x, y, w, h), area in instances:
            out.write(f"instance {instance_id} {name.replace(' ', '_')} {class_id} "
                      f"{float(score)!r} {x} {y} {w} {h} {area}\n")
        out.write("ids\n")
        for row in ids:
            out.write(" ".join(str(v) for v in row) + "\n")


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(13)
    image_masks = image_resolution_masks(rng)
    box_masks = box_resolution_masks(rng)
    onnx.save(build_model(image_masks, False, True), os.path.join(out, "image_masks.onnx"))
    onnx.save(build_model(box_masks, True, True), os.path.join(out, "box_masks.onnx"))
    onnx.save(build_model(image_masks, False, False), os.path.join(out, "no_masks.onnx"))
    for name, masks in (("image_masks", image_masks), ("box_masks", box_masks)):
        instances, ids = reference(masks)
        write_expected(os.path.join(out, name + ".txt"), instances, ids)
        print(name, [(i[1], i[5]) for i in instances])


if __name__ == "__main__":
    main()
