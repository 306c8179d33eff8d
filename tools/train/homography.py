"""Random homographies, warps and photometric changes, in PyTorch.

Homographies follow SuperPoint's ``sample_homography`` (DeTone et al. 2018):
a centred patch of the image is perturbed in perspective, scaled, rotated and
translated, each drawn from a seeded generator. A homography ``H`` maps a pixel
of the *warped* image to the source image (``x_src ~ H x_warped``), which is
what backward warping (``grid_sample``) needs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F


@dataclass(frozen=True)
class HomographyRange:
    """How far a random homography may go (SuperPoint's defaults, rotation widened)."""

    patch_ratio: float = 0.85
    perspective: float = 0.2
    scale: tuple = (0.8, 1.2)
    max_angle_deg: float = 25.0
    translation: bool = True


def _four_point_dlt(src: torch.Tensor, dst: torch.Tensor) -> torch.Tensor:
    """3x3 H with ``dst ~ H src`` from four correspondences each ([B,4,2] -> [B,3,3])."""
    b = src.shape[0]
    x, y = src[..., 0], src[..., 1]
    u, v = dst[..., 0], dst[..., 1]
    zero, one = torch.zeros_like(x), torch.ones_like(x)
    rows_u = torch.stack([x, y, one, zero, zero, zero, -u * x, -u * y], dim=-1)
    rows_v = torch.stack([zero, zero, zero, x, y, one, -v * x, -v * y], dim=-1)
    a = torch.cat([rows_u, rows_v], dim=1)  # [B,8,8]
    rhs = torch.cat([u, v], dim=1).unsqueeze(-1)
    h = torch.linalg.solve(a.double(), rhs.double()).squeeze(-1)
    h = torch.cat([h, torch.ones(b, 1, dtype=h.dtype, device=h.device)], dim=1)
    return h.view(b, 3, 3).float()


def sample_homographies(n: int, height: int, width: int, gen: torch.Generator,
                        rng: HomographyRange = HomographyRange(), identity_first: bool = False) -> torch.Tensor:
    """``n`` homographies [n,3,3] mapping warped pixels to source pixels of an image ``height x width``."""
    def uniform(lo, hi, *shape):
        return lo + (hi - lo) * torch.rand(*shape, generator=gen)

    r = rng.patch_ratio
    m = (1 - r) / 2
    corners = torch.tensor([[m, m], [m, m + r], [m + r, m + r], [m + r, m]]).expand(n, 4, 2).clone()
    # Perspective: two keystones (SuperPoint's sample_homography): the top and bottom edges'
    # ends move towards or away from each other in x, the left and right edges' ends in y,
    # each by up to min(perspective / 2, margin) of the image.
    amp = min(rng.perspective / 2, m)
    kx = uniform(-amp, amp, n)
    ky = uniform(-amp, amp, n)
    corners[:, 0, 0] += kx
    corners[:, 1, 0] -= kx
    corners[:, 2, 0] += kx
    corners[:, 3, 0] -= kx
    corners[:, 0, 1] += ky
    corners[:, 1, 1] -= ky
    corners[:, 2, 1] += ky
    corners[:, 3, 1] -= ky
    centre = corners.mean(dim=1, keepdim=True)
    scale = uniform(rng.scale[0], rng.scale[1], n).view(n, 1, 1)
    corners = (corners - centre) * scale + centre
    angle = uniform(-rng.max_angle_deg, rng.max_angle_deg, n) * math.pi / 180
    c, s = torch.cos(angle), torch.sin(angle)
    rot = torch.stack([torch.stack([c, -s], -1), torch.stack([s, c], -1)], -2)  # [n,2,2]
    corners = torch.einsum("nij,nkj->nki", rot, corners - centre) + centre
    if rng.translation:
        lo = -corners.amin(dim=1)  # shifts that keep the patch inside [0,1]^2
        hi = 1 - corners.amax(dim=1)
        shift = torch.where(hi >= lo, lo + (hi - lo) * torch.rand(n, 2, generator=gen), (lo + hi) / 2)
        corners = corners + shift.unsqueeze(1)
    if identity_first and n > 0:
        corners[0] = torch.tensor([[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]])
    unit = torch.tensor([[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]]).expand(n, 4, 2)
    size = torch.tensor([width - 1.0, height - 1.0])
    # corners are (x, y) in [0,1] of the source; the warped image's corners are the unit square.
    return _four_point_dlt(unit * size, corners * size)


def warp_points(h: torch.Tensor, pts: torch.Tensor) -> torch.Tensor:
    """Apply ``h`` [3,3] to points [N,2] (x, y)."""
    ph = torch.cat([pts, torch.ones_like(pts[:, :1])], dim=1) @ h.T
    return ph[:, :2] / ph[:, 2:3]


def warp_images(images: torch.Tensor, h: torch.Tensor, out_hw=None):
    """Backward-warp images [B,C,H,W] by ``h`` [B,3,3] (warped -> source pixel).

    Returns (warped [B,C,h,w], valid mask [B,1,h,w] of pixels that came from inside the source).
    """
    b, _, hs, ws = images.shape
    ho, wo = out_hw or (hs, ws)
    ys, xs = torch.meshgrid(torch.arange(ho, device=images.device, dtype=torch.float32),
                            torch.arange(wo, device=images.device, dtype=torch.float32), indexing="ij")
    grid = torch.stack([xs, ys, torch.ones_like(xs)], dim=-1).view(1, -1, 3)
    src = grid @ h.to(images.device).transpose(1, 2)
    src = src[..., :2] / src[..., 2:3]
    norm = torch.stack([(2 * src[..., 0] + 1) / ws - 1, (2 * src[..., 1] + 1) / hs - 1], dim=-1)
    norm = norm.view(b, ho, wo, 2)
    warped = F.grid_sample(images, norm, mode="bilinear", padding_mode="zeros", align_corners=False)
    ones = torch.ones(b, 1, hs, ws, device=images.device, dtype=images.dtype)
    valid = F.grid_sample(ones, norm, mode="nearest", padding_mode="zeros", align_corners=False)
    return warped, valid


@dataclass(frozen=True)
class PhotometricRange:
    """Photometric change of a training view: gain, gamma, blur, noise, and now and then low light."""

    gain: tuple = (0.6, 1.4)
    gamma: tuple = (0.7, 1.4)
    noise_std: tuple = (0.0, 0.03)
    blur_prob: float = 0.25
    low_light_prob: float = 0.1
    low_light_gain: tuple = (0.15, 0.4)
    low_light_noise: tuple = (0.005, 0.02)


def photometric(images: torch.Tensor, gen: torch.Generator, rng: PhotometricRange = PhotometricRange()) -> torch.Tensor:
    """Random photometric change per image of [B,1,H,W] in [0,1], clamped and quantised to 8 bits."""
    b = images.shape[0]
    dev = images.device

    def u(lo, hi):
        return (lo + (hi - lo) * torch.rand(b, 1, 1, 1, generator=gen)).to(dev)

    x = images.clamp(0, 1) ** u(*rng.gamma) * u(*rng.gain)
    blur = (torch.rand(b, generator=gen) < rng.blur_prob).to(dev).view(b, 1, 1, 1)
    k = torch.tensor([1.0, 4.0, 6.0, 4.0, 1.0], device=dev) / 16
    blurred = F.conv2d(F.pad(x, (2, 2, 2, 2), mode="replicate"), (k[:, None] * k[None, :]).view(1, 1, 5, 5))
    x = torch.where(blur, blurred, x)
    dark = (torch.rand(b, generator=gen) < rng.low_light_prob).to(dev).view(b, 1, 1, 1)
    x = torch.where(dark, x * u(*rng.low_light_gain), x)
    std = torch.where(dark, u(*rng.low_light_noise), u(*rng.noise_std))
    noise = torch.randn(x.shape, generator=gen).to(dev)
    x = x + noise * std
    return (x.clamp(0, 1) * 255).round() / 255
