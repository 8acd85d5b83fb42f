"""How real inputs differ from a clean rendering (method-notes.md, "How real goal images and goal depths differ").

- the initial view is a sensor's: image noise; ToF depth with noise growing with range, invalid pixels at depth
  discontinuities and a few dropouts;
- the goal image is an editor's: a colour gain and offset per channel, a gamma, blur, JPEG (and, done by the
  renderer, a shifted light and a partly re-textured object);
- the goal depth is a monocular model's: edges bled into the background, a slow warp of a few percent, ~1 %
  noise, and an unknown affine map in depth or in disparity;
- masks are an open-vocabulary segmenter's: a few pixels dilated or eroded, ragged edges, holes.
Each function draws its own parameters from `rng` and returns what it did, so a pair records its corruptions. Any of
them can be left out (`without`, CORRUPTIONS) with every parameter still drawn: the same scenes, poses and other
corruptions, so what one of them costs is measured on the very same pairs.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

# what a goal can be spared: the depth model's bled edges, slow warp and noise, the segmenter's mask errors, the
# editor's colour drift (blur, JPEG) and its partial re-texturing of the object
CORRUPTIONS = ("bleed", "warp", "noise", "masks", "editor", "retexture")


def sensor_image(rgb: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Float image 0..1 -> uint8 with shot-like noise."""
    noisy = rgb * 255.0 + rng.normal(0.0, rng.uniform(0.8, 2.5), rgb.shape)
    return np.clip(np.round(noisy), 0, 255).astype(np.uint8)


def sensor_depth(depth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Metric depth as a ToF camera gives it: sigma 1.5 mm at 1 m growing with range squared, NaN at most pixels
    of a depth discontinuity (flying pixels are dropped), 0.3 % random dropouts, NaN where nothing was hit."""
    d = np.where(np.isfinite(depth), depth, np.nan)
    out = d + rng.normal(0.0, 1.0, d.shape) * 0.0015 * np.nan_to_num(d, nan=1.0) ** 2
    grad = np.maximum(
        np.abs(cv2.Sobel(np.nan_to_num(d, nan=0.0), cv2.CV_64F, 1, 0, ksize=3)),
        np.abs(cv2.Sobel(np.nan_to_num(d, nan=0.0), cv2.CV_64F, 0, 1, ksize=3)),
    )
    edge = grad > 0.08  # ~2 cm between neighbours
    out[edge & (rng.random(d.shape) < 0.7)] = np.nan
    out[rng.random(d.shape) < 0.003] = np.nan
    return out.astype(np.float32)


def editor_drift(rgb: np.ndarray, rng: np.random.Generator, spared: bool = False) -> tuple[np.ndarray, dict]:
    """uint8 image -> the same picture as an image editor hands it back: colour gain/offset per channel and a gamma
    (always, mild to strong), blur and JPEG (each on about half of the images); `spared`: drawn, not done."""
    if spared:
        editor_drift(rgb, rng)
        return rgb.copy(), {}
    gain = rng.uniform(0.85, 1.15, 3)
    offset = rng.uniform(-15.0, 15.0, 3)
    gamma = rng.uniform(0.85, 1.15)
    f = (rgb.astype(np.float64) / 255.0) ** gamma * 255.0 * gain + offset
    done = {"gain": gain.round(3).tolist(), "offset": offset.round(1).tolist(), "gamma": round(gamma, 3)}
    out = np.clip(np.round(f), 0, 255).astype(np.uint8)
    if rng.random() < 0.5:
        sigma = rng.uniform(0.5, 1.5)
        out = cv2.GaussianBlur(out, (0, 0), sigma)
        done["blur_px"] = round(sigma, 2)
    if rng.random() < 0.5:
        quality = int(rng.integers(35, 90))
        _ok, buf = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].copy()
        done["jpeg_quality"] = quality
    return out, done


def smooth_field(shape: tuple[int, int], rng: np.random.Generator, waves: int = 3) -> np.ndarray:
    """A low-frequency field in -1..1: a few cosines with wavelengths of 0.6-2 image widths."""
    h, w = shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    f = np.zeros(shape)
    for _ in range(waves):
        a = rng.uniform(0, 2 * math.pi)
        k = 2 * math.pi / (rng.uniform(0.6, 2.0) * w)
        f += math.cos(rng.uniform(0, 2 * math.pi)) * np.cos(k * (u * math.cos(a) + v * math.sin(a)) + rng.uniform(0, 7))
    return f / max(np.abs(f).max(), 1e-9)


def monocular_depth(
    depth: np.ndarray, kind: str, rng: np.random.Generator, without: frozenset[str] = frozenset()
) -> tuple[np.ndarray, dict]:
    """True goal depth [m] -> a relative prediction: edges bled over 1-3 px, a 1-4 % low-frequency warp, ~1 %
    noise (correlated over a pixel), then an unknown affine map of depth or of disparity; those `without` names
    ("bleed", "warp", "noise") are drawn, not done."""
    d = np.where(np.isfinite(depth), depth, np.nanmax(np.where(np.isfinite(depth), depth, np.nan)))
    x = 1.0 / d if kind == "disparity" else d.copy()
    done: dict = {}
    bleed = rng.uniform(1.0, 3.0)
    if "bleed" not in without:
        x, done["bleed_px"] = cv2.GaussianBlur(x, (0, 0), bleed), round(bleed, 2)
    warp = rng.uniform(0.01, 0.04)
    field = smooth_field(x.shape, rng)
    if "warp" not in without:
        x, done["warp"] = x * (1.0 + warp * field), round(warp, 3)
    noise_rel = rng.uniform(0.007, 0.013)
    n = cv2.GaussianBlur(rng.normal(0.0, 1.0, x.shape), (0, 0), 1.0)
    if "noise" not in without:
        x, done["noise"] = x * (1.0 + noise_rel * n / n.std()), round(noise_rel, 4)
    if kind == "disparity":
        s, b = rng.uniform(0.3, 3.0), rng.uniform(-0.2, 0.2)
    else:
        s, b = rng.uniform(0.3, 3.0), rng.uniform(-0.5, 0.5)
    return (s * x + b).astype(np.float32), {**done, "s": s, "b": b}


def segmenter_mask(mask: np.ndarray, rng: np.random.Generator, spared: bool = False) -> tuple[np.ndarray, dict]:
    """True visible mask -> a segmenter's: dilated or eroded by up to 2-3 px, ragged edge, sometimes holes. Never
    empty (an erosion that would empty it is skipped). `spared`: drawn, not done."""
    if spared:
        segmenter_mask(mask, rng)
        return mask.copy(), {}
    out = mask.copy()
    done: dict = {}
    k = int(rng.integers(-2, 4))
    if k:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * abs(k) + 1, 2 * abs(k) + 1))
        op = cv2.dilate if k > 0 else cv2.erode
        moved = op(out.astype(np.uint8), kernel).astype(bool)
        if moved.sum() > 0.3 * out.sum():
            out = moved
            done["grow_px"] = k
    if rng.random() < 0.5:  # ragged edge: flip pixels on the boundary band
        band = cv2.dilate(out.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~cv2.erode(
            out.astype(np.uint8), np.ones((3, 3), np.uint8)
        ).astype(bool)
        flip = band & (cv2.GaussianBlur(rng.random(out.shape), (0, 0), 1.5) > 0.5)
        out = out ^ flip
        done["ragged"] = True
    if rng.random() < 0.3:
        inner = np.argwhere(cv2.erode(out.astype(np.uint8), np.ones((7, 7), np.uint8)) > 0)
        holes = int(rng.integers(1, 4))
        for _ in range(holes if len(inner) else 0):
            v, u = inner[rng.integers(len(inner))]
            cv2.circle(out.view(np.uint8), (int(u), int(v)), int(rng.integers(1, 4)), 0, -1)
        done["holes"] = holes if len(inner) else 0
    if not out.any():
        return mask.copy(), {}
    return out, done
