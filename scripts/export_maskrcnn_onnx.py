#!/usr/bin/env python3
"""Exports torchvision's Mask R-CNN to ONNX for `superdyna run --segmenter maskrcnn`.

    pip install torch torchvision onnx        # (onnxruntime too for --check)
    scripts/export_maskrcnn_onnx.py models/maskrcnn_resnet50_fpn.onnx [--variant v2]
        [--min-size 800] [--max-size 1333] [--opset 11] [--check]

The model is torchvision.models.detection.maskrcnn_resnet50_fpn (or _v2) with its COCO weights
(downloaded by torchvision on first use, about 170 MB). It is exported with torch.onnx.export as
torchvision documents and tests it: the forward takes a list of one float image, which becomes one
ONNX input [3, H, W] (RGB in [0, 1], any size: H and W are dynamic axes), and returns
  boxes [N, 4] (x1, y1, x2, y2 in input pixels), labels [N] (int64, torchvision's 91-entry COCO
  category ids), scores [N] and masks [N, 1, H, W] (soft masks pasted at the image's size),
named so here. The network resizes the image itself (--min-size / --max-size, torchvision's
800 / 1333; smaller is faster) and keeps detections above --box-score-thresh (torchvision's 0.05;
superdyna's semantics.maskrcnn_score_threshold filters again).

NOTE: written from torchvision's documented API (torchvision.models.detection, "weights" enums
since 0.13) and torch.onnx.export; it could not be run where it was written (no network access to
download the weights). Opset 11 is what torchvision's own ONNX tests use; torch >= 2.5 takes
dynamo=False to keep the TorchScript exporter those tests exercise.
"""
import argparse
import inspect
import sys


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("output", help="ONNX file to write")
    parser.add_argument("--variant", choices=["v1", "v2"], default="v1",
                        help="maskrcnn_resnet50_fpn (v1, COCO mask AP 34.6) or "
                             "maskrcnn_resnet50_fpn_v2 (v2, 41.8, slower)")
    parser.add_argument("--min-size", type=int, default=800,
                        help="shorter image side inside the network (torchvision: 800)")
    parser.add_argument("--max-size", type=int, default=1333,
                        help="longer side limit inside the network (torchvision: 1333)")
    parser.add_argument("--box-score-thresh", type=float, default=0.05,
                        help="detections the network returns at all (torchvision: 0.05)")
    parser.add_argument("--detections", type=int, default=100,
                        help="at most this many detections per image (torchvision: 100)")
    parser.add_argument("--opset", type=int, default=11, help="ONNX opset (default 11)")
    parser.add_argument("--example-size", type=int, nargs=2, default=[480, 752],
                        metavar=("H", "W"), help="size of the tracing example image")
    parser.add_argument("--check", action="store_true",
                        help="run the export with onnxruntime on another image size and compare "
                             "with PyTorch")
    return parser.parse_args()


def build_model(args):
    from torchvision.models import detection

    kwargs = dict(min_size=args.min_size, max_size=args.max_size,
                  box_score_thresh=args.box_score_thresh, box_detections_per_img=args.detections)
    if args.variant == "v2":
        weights = detection.MaskRCNN_ResNet50_FPN_V2_Weights.DEFAULT
        model = detection.maskrcnn_resnet50_fpn_v2(weights=weights, **kwargs)
    else:
        weights = detection.MaskRCNN_ResNet50_FPN_Weights.DEFAULT
        model = detection.maskrcnn_resnet50_fpn(weights=weights, **kwargs)
    return model.eval()


def export(model, args):
    import torch

    example = [torch.rand(3, *args.example_size)]
    options = dict(
        opset_version=args.opset,
        input_names=["images"],
        output_names=["boxes", "labels", "scores", "masks"],
        dynamic_axes={"images": {1: "height", 2: "width"}, "boxes": {0: "detections"},
                      "labels": {0: "detections"}, "scores": {0: "detections"},
                      "masks": {0: "detections", 2: "height", 3: "width"}},
        do_constant_folding=True)
    if "dynamo" in inspect.signature(torch.onnx.export).parameters:
        options["dynamo"] = False
    with torch.no_grad():
        torch.onnx.export(model, (example,), args.output, **options)


def check(model, args):
    """Runs PyTorch and ONNX Runtime on an image of another size than the example's."""
    import numpy as np
    import onnxruntime
    import torch

    image = torch.rand(3, args.example_size[0] + 40, args.example_size[1] - 64)
    with torch.no_grad():
        expected = model([image])[0]
    session = onnxruntime.InferenceSession(args.output, providers=["CPUExecutionProvider"])
    boxes, labels, scores, masks = session.run(None, {"images": image.numpy()})
    if len(boxes) != len(expected["boxes"]):
        sys.exit(f"check failed: {len(boxes)} detections in ONNX, {len(expected['boxes'])} in "
                 "PyTorch")
    np.testing.assert_allclose(boxes, expected["boxes"].numpy(), rtol=1e-3, atol=1e-2)
    np.testing.assert_array_equal(labels, expected["labels"].numpy())
    np.testing.assert_allclose(scores, expected["scores"].numpy(), rtol=1e-3, atol=1e-4)
    np.testing.assert_allclose(masks, expected["masks"].numpy(), rtol=1e-3, atol=1e-3)
    print(f"check: {len(boxes)} detections agree; masks {list(masks.shape)}")


def main():
    args = parse_args()
    model = build_model(args)
    export(model, args)
    print(f"wrote {args.output}: input images [3, H, W], outputs boxes, labels, scores, masks")
    if args.check:
        check(model, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
