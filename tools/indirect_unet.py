#!/usr/bin/env python3
"""The SRUG indirect-light U-Net in PyTorch, and its export to srug.

Optional for users; srug's tests do not use it. It defines the same network
as engine/src/indirect/mod.rs (ten 3x3 convolutions, padding 1):

    inc   : in -> w0                      (full resolution)
    down1 : w0 -> w1, stride 2            (1/2)
    down2 : w1 -> w2, stride 2            (1/4)
    down3 : w2 -> w3, stride 2            (1/8)
    down4 : w3 -> w4, stride 2            (1/16)
    up1   : resize(f4 to f3's size) ++ f3 -> w3
    up2   : resize(up1 to f2's size) ++ f2 -> w2
    up3   : resize(up2 to f1's size) ++ f1 -> w1
    up4   : resize(up3 to f0's size) ++ f0 -> w0
    outc  : w0 -> out (no activation)

`++` is channel concatenation, resized tensor first; every other layer is
followed by the activation. Resizing is F.interpolate(mode="bilinear") to the
skip's exact size, so any input size works.

Usage:
    python3 tools/indirect_unet.py export --out unet.safetensors [--checkpoint model.pt]
    python3 tools/indirect_unet.py sample --weights unet.safetensors --height 37 --width 23 \
        --input in.safetensors --expected expected.safetensors
    srug unet --weights unet.safetensors --input in.safetensors --out out.safetensors
    python3 tools/indirect_unet.py compare out.safetensors expected.safetensors

`export` writes the state_dict (float32, OIHW) with the architecture in the
safetensors metadata, which srug reads: architecture, in_channels, widths,
out_channels, activation (relu, leaky_relu, none), align_corners, input_order.
Needs: torch, safetensors.
"""
import argparse

import torch
import torch.nn as nn
import torch.nn.functional as F
from safetensors.torch import load_file, save_file

INPUT_ORDER = ("normal.x,normal.y,normal.z,albedo.r,albedo.g,albedo.b,roughness,metallic,"
               "sun.r,sun.g,sun.b,sky.r,sky.g,sky.b")


class IndirectUNet(nn.Module):
    def __init__(self, in_channels=14, widths=(32, 32, 64, 64, 128), out_channels=3,
                 activation="relu", align_corners=False):
        super().__init__()
        w0, w1, w2, w3, w4 = widths
        self.config = dict(in_channels=in_channels, widths=tuple(widths), out_channels=out_channels,
                           activation=activation, align_corners=align_corners)
        self.inc = nn.Conv2d(in_channels, w0, 3, padding=1)
        self.down1 = nn.Conv2d(w0, w1, 3, stride=2, padding=1)
        self.down2 = nn.Conv2d(w1, w2, 3, stride=2, padding=1)
        self.down3 = nn.Conv2d(w2, w3, 3, stride=2, padding=1)
        self.down4 = nn.Conv2d(w3, w4, 3, stride=2, padding=1)
        self.up1 = nn.Conv2d(w4 + w3, w3, 3, padding=1)
        self.up2 = nn.Conv2d(w3 + w2, w2, 3, padding=1)
        self.up3 = nn.Conv2d(w2 + w1, w1, 3, padding=1)
        self.up4 = nn.Conv2d(w1 + w0, w0, 3, padding=1)
        self.outc = nn.Conv2d(w0, out_channels, 3, padding=1)

    def act(self, x):
        a = self.config["activation"]
        if a == "relu":
            return F.relu(x)
        if a == "leaky_relu":
            return F.leaky_relu(x, 0.01)
        return x

    def up(self, x, skip, conv):
        x = F.interpolate(x, size=skip.shape[-2:], mode="bilinear",
                          align_corners=self.config["align_corners"])
        return self.act(conv(torch.cat([x, skip], dim=1)))

    def forward(self, x):
        f0 = self.act(self.inc(x))
        f1 = self.act(self.down1(f0))
        f2 = self.act(self.down2(f1))
        f3 = self.act(self.down3(f2))
        f4 = self.act(self.down4(f3))
        u = self.up(f4, f3, self.up1)
        u = self.up(u, f2, self.up2)
        u = self.up(u, f1, self.up3)
        u = self.up(u, f0, self.up4)
        return self.outc(u)

    def metadata(self):
        c = self.config
        return {
            "architecture": "srug-indirect-unet",
            "in_channels": str(c["in_channels"]),
            "widths": ",".join(str(w) for w in c["widths"]),
            "out_channels": str(c["out_channels"]),
            "activation": c["activation"],
            "align_corners": "true" if c["align_corners"] else "false",
            "input_order": INPUT_ORDER if c["in_channels"] == 14 else
            ",".join(f"input.{i}" for i in range(c["in_channels"])),
        }


def from_metadata(meta):
    return IndirectUNet(int(meta.get("in_channels", 14)),
                        tuple(int(w) for w in meta.get("widths", "32,32,64,64,128").split(",")),
                        int(meta.get("out_channels", 3)), meta.get("activation", "relu"),
                        meta.get("align_corners", "false") == "true")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("export")
    e.add_argument("--out", required=True)
    e.add_argument("--checkpoint", help="a state_dict saved with torch.save (default: random weights)")
    e.add_argument("--widths", default="32,32,64,64,128")
    e.add_argument("--activation", default="relu")
    e.add_argument("--align-corners", action="store_true")
    s = sub.add_parser("sample")
    s.add_argument("--weights", required=True)
    s.add_argument("--height", type=int, default=37)
    s.add_argument("--width", type=int, default=23)
    s.add_argument("--input", required=True)
    s.add_argument("--expected", required=True)
    c = sub.add_parser("compare")
    c.add_argument("actual")
    c.add_argument("expected")
    a = p.parse_args()
    if a.cmd == "export":
        net = IndirectUNet(widths=tuple(int(w) for w in a.widths.split(",")), activation=a.activation,
                           align_corners=a.align_corners)
        if a.checkpoint:
            net.load_state_dict(torch.load(a.checkpoint, map_location="cpu"))
        tensors = {k: v.detach().float().contiguous() for k, v in net.state_dict().items()}
        save_file(tensors, a.out, metadata=net.metadata())
    elif a.cmd == "sample":
        from safetensors import safe_open
        with safe_open(a.weights, "pt") as f:
            meta = f.metadata() or {}
        net = from_metadata(meta)
        net.load_state_dict(load_file(a.weights))
        x = torch.randn(1, net.config["in_channels"], a.height, a.width)
        with torch.no_grad():
            y = net(x)
        save_file({"input": x.contiguous()}, a.input)
        save_file({"output": y.contiguous()}, a.expected)
    else:
        d = (load_file(a.actual)["output"] - load_file(a.expected)["output"]).abs().max().item()
        print(f"max |srug - PyTorch| = {d:.3e}")


if __name__ == "__main__":
    main()
