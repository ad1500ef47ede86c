#!/usr/bin/env python3
"""Builds ONNX models with SuperPoint's contract, for running and testing SuperPointExtractor
where MagicLeap's weights are not at hand (they are not redistributable; see
scripts/export_superpoint_onnx.py for the real export).

SuperPoint's contract (features/superpoint_extractor.h):
    input  `image` [1, 1, H, W] float gray in [0, 1]
    output `semi`  [1, 65, H/8, W/8]  keypoint logits of 8x8 cells + dustbin
    output `desc`  [1, D, H/8, W/8]   dense descriptors, L2-normalised per cell

Two models:

  from-xfeat  XFeat (xfeat.onnx) behind that contract: the gray input is replicated into XFeat's
              three channels; XFeat's `keypoint_logits` become `semi` (they are SuperPoint-style
              cell logits), its 64-d `descriptors`, L2-normalised per cell, become `desc`. The
              reliability head is dropped. XFeat needs sides that are multiples of 32: the model
              says so in its metadata (superdyna.size_multiple = 32), which SuperPointExtractor
              reads.
  random      SuperPoint's architecture (VGG-style encoder 64-64-128-128 with three 2x2 max-pools,
              a 256-channel detector head ending in 65 logits and a 256-channel descriptor head
              ending in D channels, L2-normalised) with seeded random weights. Its keypoints
              mean nothing; it exercises the decoding on a network of the real shape.

Needs only Debian's python3-onnx (and numpy):
    /usr/bin/python3 scripts/make_superpoint_from_xfeat.py from-xfeat \
        --xfeat ../shared/models/xfeat.onnx --out models/superpoint_xfeat.onnx
    /usr/bin/python3 scripts/make_superpoint_from_xfeat.py random --out sp_random.onnx \
        [--seed 1] [--descriptor-size 256]
"""

import argparse
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

SIZE_MULTIPLE_KEY = "superdyna.size_multiple"


def set_metadata(model, key, value):
    for prop in model.metadata_props:
        if prop.key == key:
            prop.value = value
            return
    entry = model.metadata_props.add()
    entry.key = key
    entry.value = value


def tensor_output(name, channels):
    return helper.make_tensor_value_info(
        name, TensorProto.FLOAT, ["batch", channels, "cells_y", "cells_x"])


def prune(graph, wanted_outputs):
    """Keeps only the nodes (and initializers) the wanted outputs depend on."""
    producer = {}
    for index, node in enumerate(graph.node):
        for out in node.output:
            producer[out] = index
    needed, stack = set(), list(wanted_outputs)
    seen = set()
    while stack:
        name = stack.pop()
        if name in seen:
            continue
        seen.add(name)
        if name in producer:
            index = producer[name]
            if index not in needed:
                needed.add(index)
                stack.extend(i for i in graph.node[index].input if i)
    kept_nodes = [n for i, n in enumerate(graph.node) if i in needed]
    used = {i for n in kept_nodes for i in n.input}
    kept_init = [t for t in graph.initializer if t.name in used]
    del graph.node[:]
    graph.node.extend(kept_nodes)
    del graph.initializer[:]
    graph.initializer.extend(kept_init)


def from_xfeat(xfeat_path, out_path):
    model = onnx.load(xfeat_path)
    graph = model.graph
    if len(graph.input) != 1:
        sys.exit(f"{xfeat_path}: expected one input, found {len(graph.input)}")
    rgb_name = graph.input[0].name
    outputs = {o.name for o in graph.output}
    for name in ("keypoint_logits", "descriptors"):
        if name not in outputs:
            sys.exit(f"{xfeat_path}: output '{name}' missing (outputs: {sorted(outputs)})")
    dims = graph.input[0].type.tensor_type.shape.dim
    if len(dims) != 4 or dims[1].dim_value != 3:
        sys.exit(f"{xfeat_path}: input '{rgb_name}' is not [B,3,H,W]")

    # New input: gray [batch, 1, height, width]; three copies feed XFeat's RGB input.
    gray = helper.make_tensor_value_info("image", TensorProto.FLOAT,
                                         ["batch", 1, "height", "width"])
    to_rgb = helper.make_node("Concat", ["image", "image", "image"], [rgb_name], axis=1,
                              name="gray_to_rgb")
    semi = helper.make_node("Identity", ["keypoint_logits"], ["semi"], name="semi")
    desc = helper.make_node("LpNormalization", ["descriptors"], ["desc"], axis=1, p=2,
                            name="desc_l2")
    graph.node.insert(0, to_rgb)
    graph.node.extend([semi, desc])
    del graph.input[:]
    graph.input.extend([gray])
    del graph.output[:]
    graph.output.extend([tensor_output("semi", 65), tensor_output("desc", 64)])
    del graph.value_info[:]
    prune(graph, ["semi", "desc"])
    graph.name = "superpoint_contract_from_xfeat"
    set_metadata(model, SIZE_MULTIPLE_KEY, "32")
    model.doc_string = ("XFeat behind SuperPoint's contract (gray [B,1,H,W] -> semi, desc); "
                        "H and W multiples of 32. Made by make_superpoint_from_xfeat.py.")
    save(model, out_path)


def random_superpoint(out_path, seed, descriptor_size, logit_scale):
    rng = np.random.RandomState(seed)
    nodes, inits = [], []

    def conv(name, x, c_in, c_out, k, relu=True, scale=1.0):
        # He-normal weights keep the activations at a similar scale through the ReLU stack.
        std = scale * np.sqrt(2.0 / (c_in * k * k))
        w = (rng.standard_normal((c_out, c_in, k, k)) * std).astype(np.float32)
        b = (rng.standard_normal(c_out) * 0.01).astype(np.float32)
        inits.append(numpy_helper.from_array(w, name + ".weight"))
        inits.append(numpy_helper.from_array(b, name + ".bias"))
        out = name + ".out"
        nodes.append(helper.make_node("Conv", [x, name + ".weight", name + ".bias"], [out],
                                      kernel_shape=[k, k], pads=[k // 2] * 4, name=name))
        if not relu:
            return out
        nodes.append(helper.make_node("Relu", [out], [name + ".relu"], name=name + "_relu"))
        return name + ".relu"

    def pool(name, x):
        nodes.append(helper.make_node("MaxPool", [x], [name], kernel_shape=[2, 2],
                                      strides=[2, 2], name=name))
        return name

    x = conv("conv1a", "image", 1, 64, 3)
    x = pool("pool1", conv("conv1b", x, 64, 64, 3))
    x = conv("conv2a", x, 64, 64, 3)
    x = pool("pool2", conv("conv2b", x, 64, 64, 3))
    x = conv("conv3a", x, 64, 128, 3)
    x = pool("pool3", conv("conv3b", x, 128, 128, 3))
    x = conv("conv4a", x, 128, 128, 3)
    x = conv("conv4b", x, 128, 128, 3)
    semi = conv("convPb", conv("convPa", x, 128, 256, 3), 256, 65, 1, relu=False,
                scale=logit_scale)
    nodes.append(helper.make_node("Identity", [semi], ["semi"], name="semi"))
    d = conv("convDb", conv("convDa", x, 128, 256, 3), 256, descriptor_size, 1, relu=False)
    nodes.append(helper.make_node("LpNormalization", [d], ["desc"], axis=1, p=2, name="desc"))

    graph = helper.make_graph(
        nodes, "superpoint_random",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT,
                                       ["batch", 1, "height", "width"])],
        [tensor_output("semi", 65), tensor_output("desc", descriptor_size)], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)],
                              producer_name="make_superpoint_from_xfeat.py")
    model.ir_version = 7
    model.doc_string = (f"SuperPoint architecture with random weights (seed {seed}); "
                        "for decoding tests only.")
    onnx.checker.check_model(model)
    save(model, out_path)


def save(model, out_path):
    onnx.save(model, out_path)
    print(f"wrote {out_path}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    a = sub.add_parser("from-xfeat", help="XFeat behind SuperPoint's contract")
    a.add_argument("--xfeat", required=True, help="xfeat.onnx")
    a.add_argument("--out", required=True)
    b = sub.add_parser("random", help="SuperPoint architecture, random weights")
    b.add_argument("--out", required=True)
    b.add_argument("--seed", type=int, default=1)
    b.add_argument("--descriptor-size", type=int, default=256)
    b.add_argument("--logit-scale", type=float, default=4.0,
                   help="scale of the last detector layer's weights (spread of the logits)")
    args = parser.parse_args()
    if args.mode == "from-xfeat":
        from_xfeat(args.xfeat, args.out)
    else:
        if args.descriptor_size < 1:
            sys.exit("--descriptor-size must be >= 1")
        random_superpoint(args.out, args.seed, args.descriptor_size, args.logit_scale)


if __name__ == "__main__":
    main()
