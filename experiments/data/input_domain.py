"""Thresholds of :mod:`cerberus_core.reconstruct.input_domain`, measured (docs/evaluation.md, "Input outside the
training domain").

Generated images (a dataset's test split and its first 200 training images, saved as PNG, as JPEG
quality 75 and at 4x the size) must all pass the background check; the same bodies pasted on cluttered
backgrounds (noise, gradients, smooth blobs, 1/f texture, rectangles, white, grey, a dark texture) and
portraits (head to waist, zoomed) and close-ups (the head, zoomed) must fail. Without a silhouette, a body
cut off by the frame is found from the image alone (``estimated_foreground``): portraits and close-ups on
the training background or on a plain wall must be named cut off, no whole body may be. Prints the border
statistics per group, the share in domain and the share named cut off, then how many generated
silhouettes the framing leaves as they are:

    python experiments/data/input_domain.py data/human
"""
from __future__ import annotations

import argparse
import io
import tempfile
import warnings
from pathlib import Path

import numpy as np
from PIL import Image

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.readers import ViewDataset
from cerberus_core.reconstruct import input_domain as D

RNG = np.random.default_rng(0)


def images(ds: ViewDataset, n: int) -> list[np.ndarray]:
    out = []
    for i in range(min(n, len(ds))):
        x = ds[i]["images"]
        out.append((x[0] if x.dim() == 4 else x).numpy().transpose(1, 2, 0).astype(np.float64))
    return out


def border_stats(arr: np.ndarray, bg: np.ndarray) -> tuple[float, float, float]:
    """Fraction of the ring on the background, its colour spread, the largest fraction of one side off it."""
    sides = D._ring(arr, D.BORDER_WIDTH)
    ring = np.concatenate(list(sides.values()))

    def near(px: np.ndarray) -> np.ndarray:
        return np.abs(px - bg).max(-1) <= D.BACKGROUND_TOLERANCE

    return float(near(ring).mean()), float(ring.std(0).max()), max(float(1 - near(p).mean()) for p in sides.values())


def as_model_sees(arr: np.ndarray, scene, tmp: Path, fmt: str = "PNG", scale: int = 1, size: int | None = None,
                  **kw) -> np.ndarray:
    """``arr`` saved as a file (``fmt``, ``scale`` times the size) and read back by ``prepare_input`` for a model of
    ``size`` pixels (default the array's own)."""
    im = Image.fromarray((np.clip(arr, 0, 1) * 255).round().astype(np.uint8))
    if scale != 1:
        im = im.resize((im.width * scale, im.height * scale), Image.LANCZOS)
    buf = io.BytesIO()
    im.save(buf, fmt, **kw)
    path = tmp / f"m.{fmt.lower()}"
    path.write_bytes(buf.getvalue())
    return D.prepare_input(path, size or arr.shape[0], scene, warn=False).image.numpy().transpose(1, 2, 0)


def silhouette(arr: np.ndarray, bg: np.ndarray) -> np.ndarray:
    return (np.abs(arr - bg).max(-1) > 0.02).astype(np.float64)


def smooth(n: int, k: int = 6) -> np.ndarray:
    low = (RNG.random((k, k, 3)) * 255).astype(np.uint8)
    return np.asarray(Image.fromarray(low).resize((n, n), Image.BICUBIC)) / 255.0


def one_over_f(n: int) -> np.ndarray:
    f = np.fft.fftfreq(n)[:, None] ** 2 + np.fft.fftfreq(n)[None] ** 2
    f[0, 0] = 1
    out = np.stack([np.real(np.fft.ifft2(np.fft.fft2(RNG.normal(size=(n, n))) / f ** 0.75)) for _ in range(3)], -1)
    return (out - out.min()) / (out.max() - out.min())


def rectangles(n: int) -> np.ndarray:
    a = np.ones((n, n, 3)) * RNG.random(3)
    for _ in range(12):
        y, x = RNG.integers(0, n, 2)
        h, w = RNG.integers(4, n // 2, 2)
        a[y:y + h, x:x + w] = RNG.random(3)
    return a


def backgrounds(n: int, bg: np.ndarray) -> dict:
    ramp = np.linspace(0, 1, n)
    return {
        "uniform noise": lambda: RNG.random((n, n, 3)),
        "noise sigma 0.1 around the background": lambda: np.clip(bg + RNG.normal(0, 0.1, (n, n, 3)), 0, 1),
        "horizontal gradient": lambda: np.broadcast_to(ramp[None, :, None] * RNG.random(3), (n, n, 3)),
        "vertical gradient": lambda: np.broadcast_to(ramp[:, None, None] * RNG.random(3), (n, n, 3)),
        "smooth colour blobs": lambda: smooth(n),
        "1/f texture": lambda: one_over_f(n),
        "rectangles": lambda: rectangles(n),
        "white": lambda: np.ones((n, n, 3)),
        "grey 0.5": lambda: np.full((n, n, 3), 0.5),
        "dark texture 0..0.3": lambda: 0.3 * one_over_f(n),
    }


def portrait(arr: np.ndarray, bg: np.ndarray) -> np.ndarray:
    """Head to waist, zoomed to fill a square: the body runs along the bottom edge."""
    s = silhouette(arr, bg)
    rows, cols = np.nonzero(s.any(1))[0], np.nonzero(s.any(0))[0]
    top, cut = rows[0], rows[0] + (rows[-1] - rows[0]) // 2
    side = cut - top + 4
    left = (cols[0] + cols[-1]) // 2 - side // 2
    pad = np.pad(arr, ((side, side), (side, side), (0, 0)), mode="edge")
    return np.ascontiguousarray(pad[top - 4 + side:cut + side, left + side:left + 2 * side])


def closeup(arr: np.ndarray, bg: np.ndarray) -> np.ndarray:
    """A square 30 % of the body high from its top (the head and shoulders), centred on the head (the top
    rows' body pixels), zoomed to fill the frame."""
    s = silhouette(arr, bg)
    rows = np.nonzero(s.any(1))[0]
    side = max(4, int(0.3 * (rows[-1] - rows[0])))
    head = np.nonzero(s[rows[0]:rows[0] + max(2, side // 3)].any(0))[0]
    top, left = rows[0] - 2, int(head.mean()) - side // 2
    pad = np.pad(arr, ((side, side), (side, side), (0, 0)), mode="edge")
    return np.ascontiguousarray(pad[top + side:top + 2 * side, left + side:left + 2 * side])


#: A plain wall behind the body (a photo's background, not the training one).
WALL = np.array([0.85, 0.8, 0.7])


def on_wall(arr: np.ndarray, bg: np.ndarray) -> np.ndarray:
    m = silhouette(arr, bg)[..., None]
    return arr * m + WALL * (1 - m)


def report(name: str, arrs: list[np.ndarray], scene, want: str, want_cut: str = "0%") -> None:
    """A table row: the border statistics, the share in domain, the share named cut off without a silhouette
    (``estimated_foreground``, ``cut_off_sides``) and the share whose body could not be told from its border."""
    bg = np.asarray(scene.background, dtype=np.float64)
    s = np.array([border_stats(a, bg) for a in arrs])
    fgs = [D.estimated_foreground(a, scene) for a in arrs]
    cut = np.array([fg is not None and bool(D.cut_off_sides(fg)) for fg in fgs])
    ok = np.array([D.background_check(a, scene, D.cut_off_sides(fg) if fg is not None else ())[0]
                   for a, fg in zip(arrs, fgs, strict=True)]) & ~cut
    print(f"| {name} | {len(arrs)} | {s[:, 0].min():.3f} | {np.median(s[:, 0]):.3f} | {s[:, 1].max():.3f} | "
          f"{s[:, 2].max():.3f} | {ok.mean():.0%} (want {want}) | {cut.mean():.0%} (want {want_cut}) | "
          f"{np.mean([fg is None for fg in fgs]):.0%} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("root", help="a generated dataset folder")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    test = Dataset.open(args.root).views(split="test")
    scene, bg = test.scene, np.asarray(test.scene.background, dtype=np.float64)
    gen = images(test, 10_000) + images(Dataset.open(args.root).views(split="train"), 200)
    tmp = Path(tempfile.mkdtemp())
    print("| images | n | border on the background, min | median | border spread, max | one side off, max | in domain "
          "| cut off (no silhouette) | body not told from the border |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    report("generated (PNG)", [as_model_sees(a, scene, tmp) for a in gen], scene, "100%")
    report("generated (JPEG q75)", [as_model_sees(a, scene, tmp, "JPEG", quality=75) for a in gen], scene, "100%")
    report("generated (4x, PNG)", [as_model_sees(a, scene, tmp, scale=4) for a in gen[:150]], scene, "100%")
    for name, make in backgrounds(gen[0].shape[0], bg).items():
        pasted = []
        for a in gen[:100]:
            m = silhouette(a, bg)[..., None]
            pasted.append(as_model_sees(a * m + make() * (1 - m), scene, tmp))
        report(f"body on {name}", pasted, scene, "0%")
    n = gen[0].shape[0]  # crops are resized to the model's size, as an image of another size is
    portraits = [portrait(a, bg) for a in gen[:208]]
    report("portrait (head to waist, zoomed)", [as_model_sees(p, scene, tmp, size=n) for p in portraits], scene, "0%",
           "100%")
    report("close-up (head and shoulders, zoomed)", [as_model_sees(closeup(a, bg), scene, tmp, size=n)
                                                     for a in gen[:208]], scene, "0%", "100%")
    walled = [on_wall(a, bg) for a in gen[:208]]
    report("whole body on a plain wall", [as_model_sees(w, scene, tmp) for w in walled], scene, "0%")
    report("portrait on a plain wall", [as_model_sees(portrait(w, WALL), scene, tmp, size=n) for w in walled], scene,
           "0%", "100%")
    report("close-up on a plain wall", [as_model_sees(closeup(w, WALL), scene, tmp, size=n) for w in walled], scene,
           "0%", "100%")
    print("portrait silhouettes cut off:", np.mean([bool(D.cut_off_sides(silhouette(p, bg))) for p in portraits]))
    print("generated silhouettes cut off:", np.mean([bool(D.cut_off_sides(silhouette(a, bg))) for a in gen]))
    print("generated silhouettes left unframed:", np.mean([D.training_window(silhouette(a, bg), scene) is None
                                                           for a in gen]))


if __name__ == "__main__":
    main()
