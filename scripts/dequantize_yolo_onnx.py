#!/usr/bin/env python3
"""Writes an fp32 copy of an ONNX model quantised by ONNX Runtime's dynamic quantisation.

quantize_dynamic turns each Conv into DynamicQuantizeLinear (the activation) -> ConvInteger ->
Cast -> Mul (activation scale x weight scale) -> Add (bias). On CPU the int8 ConvInteger path of
yolov8n-seg-int8.onnx is slower than float convolutions. This script puts a float Conv back in
place of ConvInteger, Cast and Mul, with the weights dequantised ((w_q - zero_point) x scale, per
tensor or per output channel), keeps the bias Add, and drops the nodes and initialisers left
unused. The result computes what the int8 model computes up to the activation quantisation
(which it no longer does). Needs python3-onnx.

  dequantize_yolo_onnx.py IN.onnx OUT.onnx
"""
import sys

import numpy as np
import onnx
from onnx import helper, numpy_helper


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    model = onnx.load(sys.argv[1])
    graph = model.graph
    inits = {t.name: t for t in graph.initializer}
    producer = {o: n for n in graph.node for o in n.output}
    consumers = {}
    for n in graph.node:
        for i in n.input:
            consumers.setdefault(i, []).append(n)

    replaced, new_inits = 0, []
    remove = set()
    for conv in [n for n in graph.node if n.op_type == "ConvInteger"]:
        x_q, w_q, _, w_zp = (list(conv.input) + [""] * 4)[:4]
        quantize = producer[x_q]
        if quantize.op_type != "DynamicQuantizeLinear":
            raise SystemExit(f"{conv.name}: input not from DynamicQuantizeLinear")
        (cast,) = consumers[conv.output[0]]
        (mul,) = consumers[cast.output[0]]
        if cast.op_type != "Cast" or mul.op_type != "Mul":
            raise SystemExit(f"{conv.name}: not followed by Cast and Mul")
        scales = producer[[i for i in mul.input if i != cast.output[0]][0]]
        w_scale = [i for i in scales.input if i in inits][0]
        weight = numpy_helper.to_array(inits[w_q]).astype(np.float32)
        zero = numpy_helper.to_array(inits[w_zp]).astype(np.float32) if w_zp else np.float32(0)
        scale = numpy_helper.to_array(inits[w_scale]).astype(np.float32)
        shape = (-1,) + (1,) * (weight.ndim - 1)
        if np.ndim(zero) == 1:
            zero = zero.reshape(shape)
        if np.ndim(scale) == 1:
            scale = scale.reshape(shape)
        name = w_q.replace("_quantized", "") + "_dequantized"
        new_inits.append(numpy_helper.from_array((weight - zero) * scale, name))
        float_conv = helper.make_node("Conv", [quantize.input[0], name], [mul.output[0]],
                                      name=conv.name.replace("_quant", ""))
        float_conv.attribute.extend(conv.attribute)
        graph.node.insert(list(graph.node).index(conv), float_conv)
        remove.update(id(n) for n in (conv, cast, mul, scales))
        replaced += 1
    kept = [n for n in graph.node if id(n) not in remove]
    del graph.node[:]
    graph.node.extend(kept)
    graph.initializer.extend(new_inits)

    # Drop what nothing uses any more (the DynamicQuantizeLinear nodes, the int8 weights).
    outputs = {o.name for o in graph.output}
    while True:
        used = {i for n in graph.node for i in n.input} | outputs
        dead = [n for n in graph.node if not any(o in used for o in n.output)]
        if not dead:
            break
        for n in dead:
            graph.node.remove(n)
    used = {i for n in graph.node for i in n.input}
    unused = [t for t in graph.initializer if t.name not in used]
    for t in unused:
        graph.initializer.remove(t)
    del graph.value_info[:]
    for prop in model.metadata_props:
        if prop.key == "onnx.infer":
            prop.value = "dequantized from onnxruntime.quant"
    onnx.save(model, sys.argv[2])
    left = sum(n.op_type in ("ConvInteger", "DynamicQuantizeLinear") for n in graph.node)
    print(f"wrote {sys.argv[2]}: {replaced} ConvInteger -> Conv, {len(unused)} initialisers "
          f"dropped, {left} quantisation nodes left")
    return 0


if __name__ == "__main__":
    sys.exit(main())
