#!/usr/bin/env python3
"""Exports MagicLeap's pretrained SuperPoint (superpoint_v1.pth) to ONNX with the contract that
SuperPointExtractor (include/superdyna/features/superpoint_extractor.h) expects:

    input  `image` [1, 1, H, W] float32 gray in [0, 1], H and W multiples of 8 (dynamic)
    output `semi`  [1, 65, H/8, W/8]  keypoint logits: 64 pixels of each 8x8 cell + dustbin
    output `desc`  [1, 256, H/8, W/8] dense descriptors, L2-normalised per cell

The weights are not part of this repository (MagicLeap's licence does not allow redistributing
them): take superpoint_v1.pth from MagicLeap's SuperPointPretrainedNetwork release and read its
licence. The network below is the architecture described in DeTone et al., "SuperPoint:
Self-Supervised Interest Point Detection and Description" (CVPRW 2018), with the layer names
of that release so that its state dict loads as it is.

Needs PyTorch (not available as a Debian bookworm package; `pip install torch` in a virtual
environment) and, for --check, onnxruntime's Python package:

    python3 scripts/export_superpoint_onnx.py --weights superpoint_v1.pth \
        --out models/superpoint.onnx [--opset 17] [--check]

then run with SUPERDYNA_MODEL_DIR pointing at the folder, or put the file into models/.
"""

import argparse
import sys

try:
    import torch
    import torch.nn.functional as F
    from torch import nn
except ImportError:  # pragma: no cover - depends on the machine
    sys.exit("PyTorch is needed: pip install torch (in a virtual environment)")


class SuperPointNet(nn.Module):
    """Shared VGG-style encoder (1/8 resolution, 128 channels) with a detector head (65 logits
    per cell) and a descriptor head (256-d per cell, unit length)."""

    def __init__(self):
        super().__init__()
        c1, c2, c3, c4, c5, d1 = 64, 64, 128, 128, 256, 256
        self.relu = nn.ReLU(inplace=True)
        self.pool = nn.MaxPool2d(kernel_size=2, stride=2)
        self.conv1a = nn.Conv2d(1, c1, kernel_size=3, stride=1, padding=1)
        self.conv1b = nn.Conv2d(c1, c1, kernel_size=3, stride=1, padding=1)
        self.conv2a = nn.Conv2d(c1, c2, kernel_size=3, stride=1, padding=1)
        self.conv2b = nn.Conv2d(c2, c2, kernel_size=3, stride=1, padding=1)
        self.conv3a = nn.Conv2d(c2, c3, kernel_size=3, stride=1, padding=1)
        self.conv3b = nn.Conv2d(c3, c3, kernel_size=3, stride=1, padding=1)
        self.conv4a = nn.Conv2d(c3, c4, kernel_size=3, stride=1, padding=1)
        self.conv4b = nn.Conv2d(c4, c4, kernel_size=3, stride=1, padding=1)
        # Detector head.
        self.convPa = nn.Conv2d(c4, c5, kernel_size=3, stride=1, padding=1)
        self.convPb = nn.Conv2d(c5, 65, kernel_size=1, stride=1, padding=0)
        # Descriptor head.
        self.convDa = nn.Conv2d(c4, c5, kernel_size=3, stride=1, padding=1)
        self.convDb = nn.Conv2d(c5, d1, kernel_size=1, stride=1, padding=0)

    def forward(self, image):
        x = self.relu(self.conv1a(image))
        x = self.pool(self.relu(self.conv1b(x)))
        x = self.relu(self.conv2a(x))
        x = self.pool(self.relu(self.conv2b(x)))
        x = self.relu(self.conv3a(x))
        x = self.pool(self.relu(self.conv3b(x)))
        x = self.relu(self.conv4a(x))
        x = self.relu(self.conv4b(x))
        semi = self.convPb(self.relu(self.convPa(x)))
        desc = self.convDb(self.relu(self.convDa(x)))
        desc = F.normalize(desc, p=2.0, dim=1)
        return semi, desc


def load_weights(model, path):
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except TypeError:  # PyTorch < 1.13 has no weights_only
        state = torch.load(path, map_location="cpu")
    if isinstance(state, dict) and "state_dict" in state:
        state = state["state_dict"]
    # Checkpoints saved from nn.DataParallel prefix every key with "module.".
    state = {k[len("module."):] if k.startswith("module.") else k: v for k, v in state.items()}
    missing, unexpected = model.load_state_dict(state, strict=False)
    if missing or unexpected:
        sys.exit(f"{path}: not a SuperPoint state dict (missing {missing}, unexpected {unexpected})")


def check_with_onnxruntime(model, out_path):
    import numpy as np
    import onnxruntime as ort

    session = ort.InferenceSession(out_path, providers=["CPUExecutionProvider"])
    for height, width in ((240, 320), (480, 752)):  # a size other than the export's
        image = torch.rand(1, 1, height, width, generator=torch.Generator().manual_seed(0))
        with torch.no_grad():
            semi, desc = model(image)
        ort_semi, ort_desc = session.run(["semi", "desc"], {"image": image.numpy()})
        err = max(np.abs(ort_semi - semi.numpy()).max(), np.abs(ort_desc - desc.numpy()).max())
        print(f"check {width}x{height}: semi {ort_semi.shape}, desc {ort_desc.shape}, "
              f"max |onnxruntime - torch| = {err:.2e}")
        if err > 1e-3:
            sys.exit("onnxruntime and PyTorch disagree")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--weights", required=True, help="superpoint_v1.pth")
    parser.add_argument("--out", required=True, help="output .onnx file")
    parser.add_argument("--opset", type=int, default=17)
    parser.add_argument("--check", action="store_true",
                        help="compare onnxruntime's outputs with PyTorch's on random images")
    args = parser.parse_args()

    model = SuperPointNet().eval()
    load_weights(model, args.weights)
    example = torch.zeros(1, 1, 480, 640)
    torch.onnx.export(
        model, (example,), args.out,
        input_names=["image"], output_names=["semi", "desc"],
        dynamic_axes={"image": {2: "height", 3: "width"},
                      "semi": {2: "cells_y", 3: "cells_x"},
                      "desc": {2: "cells_y", 3: "cells_x"}},
        opset_version=args.opset, do_constant_folding=True)
    print(f"wrote {args.out}")
    if args.check:
        check_with_onnxruntime(model, args.out)


if __name__ == "__main__":
    main()
