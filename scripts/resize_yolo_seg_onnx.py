#!/usr/bin/env python3
"""Writes a copy of an Ultralytics YOLOv8-seg ONNX export (fixed input size) for another input size.

An export with dynamic=False bakes its input size into a few constants of the detection head: the
anchor-point grid and the stride per anchor of the box decoding, and the anchor count of two
Reshape shapes. The convolutions and the prototype branch do not depend on the size. This script
regenerates those constants for the new size (anchor points at cell centres, row by row, for
strides 8, 16, 32, as Ultralytics' make_anchors does), after checking that it reproduces the
original ones for the original size, and sets the input and output shapes. Needs python3-onnx.

  resize_yolo_seg_onnx.py IN.onnx OUT.onnx SIZE        (SIZE: a multiple of 32, e.g. 640)
"""
import sys

import numpy as np
import onnx
from onnx import numpy_helper

STRIDES = (8, 16, 32)


def anchors_for(height, width):
    points, strides = [], []
    for s in STRIDES:
        ys, xs = np.meshgrid(np.arange(height // s) + 0.5, np.arange(width // s) + 0.5,
                             indexing="ij")
        points.append(np.stack([xs.ravel(), ys.ravel()]))
        strides.append(np.full(xs.size, s, dtype=np.float32))
    return np.concatenate(points, axis=1).astype(np.float32)[None], np.concatenate(strides)[None]


def input_size(model):
    dims = model.graph.input[0].type.tensor_type.shape.dim
    return dims[2].dim_value, dims[3].dim_value


def main():
    if len(sys.argv) != 4:
        print(__doc__)
        return 2
    source, target, size = sys.argv[1], sys.argv[2], int(sys.argv[3])
    if size <= 0 or size % 32:
        print("SIZE must be a positive multiple of 32")
        return 2
    model = onnx.load(source)
    height, width = input_size(model)
    old_points, old_strides = anchors_for(height, width)
    count = old_points.shape[2]
    new_points, new_strides = anchors_for(size, size)
    new_count = new_points.shape[2]
    replaced = {"points": 0, "strides": 0, "shapes": 0}
    for tensor in model.graph.initializer:
        value = numpy_helper.to_array(tensor)
        if value.shape == old_points.shape and value.dtype == np.float32:
            if not np.array_equal(value, old_points):
                raise SystemExit(f"{tensor.name}: not the anchor grid this script computes")
            tensor.CopyFrom(numpy_helper.from_array(new_points, tensor.name))
            replaced["points"] += 1
        elif value.shape == old_strides.shape and value.dtype == np.float32:
            if not np.array_equal(value, old_strides):
                raise SystemExit(f"{tensor.name}: not the strides this script computes")
            tensor.CopyFrom(numpy_helper.from_array(new_strides, tensor.name))
            replaced["strides"] += 1
        elif value.dtype == np.int64 and value.ndim == 1 and value.size in (3, 4) \
                and value[-1] == count:
            value = value.copy()
            value[-1] = new_count
            tensor.CopyFrom(numpy_helper.from_array(value, tensor.name))
            replaced["shapes"] += 1
    if replaced["points"] < 1 or replaced["strides"] < 1 or replaced["shapes"] < 1:
        raise SystemExit(f"unexpected graph: replaced {replaced}")
    dims = model.graph.input[0].type.tensor_type.shape.dim
    dims[2].dim_value = size
    dims[3].dim_value = size
    for output in model.graph.output:
        d = output.type.tensor_type.shape.dim
        if len(d) == 3:
            d[2].dim_value = new_count
        elif len(d) == 4:
            d[2].dim_value = size // 4
            d[3].dim_value = size // 4
    del model.graph.value_info[:]  # shapes inferred for the old size
    for prop in model.metadata_props:
        if prop.key == "imgsz":
            prop.value = f"[{size}, {size}]"
    onnx.save(model, target)
    print(f"wrote {target}: input {size}x{size}, {new_count} anchors (was {height}x{width}, "
          f"{count}); replaced {replaced}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
