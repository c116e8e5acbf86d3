"""Benchmark: the renderer in Cerberus's training workload, per backend, against one CNN training step.

One training batch renders 128 images (16 quadruplets x 4 images x 2 viewpoints) of 9 parts x 320
faces at 64x64 or 128x128 pixels, forward and backward (an MSE loss against target images). For each
installed renderer backend (and Mitsuba 3, if installed) the script prints the median milliseconds
per batch and the ratio to one training step (forward, backward, Adam step) of a ResNet-10-v1 on 64
images of the same resolution, beside the project's targets on a 2-core CPU:

* warp  <= 0.1 x the CNN step, and >= 10x faster than torch;
* torch <= 0.5 x the CNN step.

Run:  python benchmarks/bench_render.py [--sizes 64 128] [--repeats 5] [--backends torch warp mitsuba]
                                        [--json out.json] [--threads N]

The scenes: 9 deformed ellipsoid parts forming a stick figure inside [-0.5, 0.5]^3 (the demo figure of
``cerberus demo``), each body with its own random part rotations (its pose), seen from distance 2.5
with a 30 degree field of view at random azimuths and 15 degrees elevation.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from kornia.geometry.conversions import axis_angle_to_rotation_matrix

from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import available_renderers, make_renderer
from cerberus_core.render.camera import Camera
from cerberus_core.render.demo import demo_scene
from cerberus_core.render.light import Light
from cerberus_core.viz import part_colors

Tensor = torch.Tensor

QUADRUPLETS, IMAGES, VIEWPOINTS = 16, 4, 2  # 128 renders per batch
CNN_IMAGES = 64
DISTANCE, FOV, ELEVATION = 2.5, 30.0, 15.0
TARGETS = {"warp": 0.1, "torch": 0.5}  # largest allowed ratio to the CNN step
WARP_SPEEDUP = 10.0  # warp must be at least this many times faster than torch


# --------------------------------------------------------------------------------------------- workload
@dataclass
class Workload:
    """One training batch of renders.

    Attributes:
        parts: ``(N, 9, 162, 3)`` part vertices (world units), ``N = 128``.
        faces: ``(320, 3)`` the template's faces.
        camera: ``N`` cameras.
        albedo: ``(9, 3)`` part colours.
        target: ``(N, 3, S, S)`` images the loss compares with.
    """

    parts: Tensor
    faces: Tensor
    camera: Camera
    albedo: Tensor
    target: Tensor = field(repr=False)

    @property
    def size(self) -> int:
        return self.camera.height


def training_batch(size: int, seed: int = 0) -> Workload:
    """The renders of one training batch at ``size`` x ``size`` pixels.

    Each of the 16 quadruplets shows one body in 2 poses from 2 viewpoints (4 images); the parts
    predicted from every image are rendered from both viewpoints (the viewpoint-consistency loss).
    """
    g = torch.Generator().manual_seed(seed)
    rest, faces, _ = demo_scene(batch=1, image_size=size, seed=seed)
    rest = rest[0]  # (9, 162, 3)
    nparts = rest.shape[0]
    centres = rest.mean(1, keepdim=True)
    bodies = QUADRUPLETS * 2  # two poses per quadruplet
    angles = 0.5 * (torch.rand(bodies * nparts, 3, generator=g) - 0.5)  # up to ~14 degrees per axis
    rot = axis_angle_to_rotation_matrix(angles).view(bodies, nparts, 3, 3)
    posed = (rest - centres) @ rot.transpose(-1, -2) + centres  # each part turns about its centre
    posed = posed * (0.9 + 0.2 * torch.rand(bodies, 1, 1, 1, generator=g))
    # Render order: quadruplet, pose, input viewpoint, render viewpoint.
    parts = posed.view(QUADRUPLETS, 2, 1, 1, nparts, -1, 3).expand(-1, -1, 2, VIEWPOINTS, -1, -1, -1)
    parts = parts.reshape(-1, nparts, rest.shape[1], 3).contiguous()
    parts = parts + 0.003 * torch.randn(parts.shape, generator=g)  # each image predicts slightly different parts
    azimuth = 360.0 * torch.rand(QUADRUPLETS, 1, 1, VIEWPOINTS, generator=g)
    azimuth = azimuth.expand(-1, 2, 2, -1).reshape(-1)
    camera = Camera.look_at(azimuth, ELEVATION, DISTANCE, fov_y_deg=FOV, image_size=size)
    albedo = part_colors(nparts)
    with torch.no_grad():
        target = render_parts(make_renderer(available_renderers()[0]), parts.roll(1, 0), faces, camera,
                              albedo=albedo).image
    return Workload(parts, faces, camera, albedo, target)


# --------------------------------------------------------------------------------------------- timing
@dataclass
class Timing:
    """Median milliseconds of a timed callable (``forward`` / ``backward`` where they are split)."""

    total_ms: float
    forward_ms: float | None = None
    backward_ms: float | None = None
    samples_ms: list[float] = field(default_factory=list)

    @property
    def min_ms(self) -> float:
        """The fastest repeat: less disturbed than the median by other load on a shared machine."""
        return min(self.samples_ms)


def time_split(step: Callable[[], tuple[float, float]], repeats: int, warmup: int) -> Timing:
    """Run ``step`` (returning its forward and backward seconds) ``warmup + repeats`` times."""
    for _ in range(warmup):
        step()
    fwd, bwd = [], []
    for _ in range(repeats):
        f, b = step()
        fwd.append(f * 1e3)
        bwd.append(b * 1e3)
    tot = [f + b for f, b in zip(fwd, bwd, strict=False)]
    return Timing(statistics.median(tot), statistics.median(fwd), statistics.median(bwd), tot)


def renderer_step(name: str, work: Workload) -> Callable[[], tuple[float, float]]:
    """Forward (render + MSE loss) and backward of one batch with a cerberus backend."""
    renderer = make_renderer(name)
    light = Light.following(work.camera)

    def step() -> tuple[float, float]:
        parts = work.parts.clone().requires_grad_(True)
        t0 = time.perf_counter()
        out = render_parts(renderer, parts, work.faces, work.camera, light, albedo=work.albedo)
        loss = torch.nn.functional.mse_loss(out.image, work.target)
        t1 = time.perf_counter()
        loss.backward()
        t2 = time.perf_counter()
        if not torch.isfinite(parts.grad).all():
            raise RuntimeError(f"renderer '{name}' produced non-finite gradients")
        return t1 - t0, t2 - t1

    return step


# --------------------------------------------------------------------------------------------- CNN step
class _BasicBlock(torch.nn.Module):
    def __init__(self, cin: int, cout: int, stride: int) -> None:
        super().__init__()
        self.conv1 = torch.nn.Conv2d(cin, cout, 3, stride, 1, bias=False)
        self.bn1 = torch.nn.BatchNorm2d(cout)
        self.conv2 = torch.nn.Conv2d(cout, cout, 3, 1, 1, bias=False)
        self.bn2 = torch.nn.BatchNorm2d(cout)
        self.short = (torch.nn.Sequential(torch.nn.Conv2d(cin, cout, 1, stride, bias=False), torch.nn.BatchNorm2d(cout))
                      if stride != 1 or cin != cout else torch.nn.Identity())

    def forward(self, x: Tensor) -> Tensor:
        y = torch.relu(self.bn1(self.conv1(x)))
        return torch.relu(self.bn2(self.conv2(y)) + self.short(x))


def _compact_resnet10() -> torch.nn.Module:
    """ResNet-10 v1: 7x7/2 stem + max-pool, one BasicBlock per stage, channels 64, 128, 256, 512."""
    return torch.nn.Sequential(
        torch.nn.Conv2d(3, 64, 7, 2, 3, bias=False), torch.nn.BatchNorm2d(64), torch.nn.ReLU(),
        torch.nn.MaxPool2d(3, 2, 1),
        _BasicBlock(64, 64, 1), _BasicBlock(64, 128, 2), _BasicBlock(128, 256, 2), _BasicBlock(256, 512, 2))


def resnet10_model() -> tuple[torch.nn.Module, str]:
    """The toolkit's encoder if it exists, else the compact ResNet-10 v1 above; and which one it is."""
    try:
        from cerberus_core.model.encoder import resnet10
    except ImportError:
        return _compact_resnet10(), "ResNet-10 v1 defined in this benchmark (cerberus_core.model.encoder not found)"
    return resnet10(), "cerberus_core.model.encoder.resnet10 (ResNet-10 v1, 64/128/256/512 channels)"


def _scalar(out) -> Tensor:
    """A scalar loss from whatever the network returns (tensor, sequence, dict or dataclass of tensors)."""
    if isinstance(out, Tensor):
        return out.float().square().mean()
    if dataclasses.is_dataclass(out):
        out = [getattr(out, f.name) for f in dataclasses.fields(out)]
    if isinstance(out, dict):
        out = list(out.values())
    return sum(_scalar(o) for o in out if isinstance(o, Tensor) or dataclasses.is_dataclass(o)
               or isinstance(o, (list, tuple, dict)))


def cnn_step(size: int, model: torch.nn.Module) -> Callable[[], tuple[float, float]]:
    """One training step of the CNN on 64 images: forward, backward and Adam (the backward time
    includes the Adam step)."""
    opt = torch.optim.Adam(model.parameters(), lr=5e-4)
    images = torch.rand(CNN_IMAGES, 3, size, size, generator=torch.Generator().manual_seed(size))

    def step() -> tuple[float, float]:
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        loss = _scalar(model(images))
        t1 = time.perf_counter()
        loss.backward()
        opt.step()
        t2 = time.perf_counter()
        return t1 - t0, t2 - t1

    return step


# --------------------------------------------------------------------------------------------- Mitsuba
def mitsuba_status() -> str | None:
    """None if Mitsuba 3 with the ``llvm_ad_rgb`` variant works here, else why not."""
    try:
        import mitsuba as mi
    except ImportError:
        return "not installed (optional: pip install mitsuba)"
    if "llvm_ad_rgb" not in mi.variants():
        return f"mitsuba {mi.__version__} has no llvm_ad_rgb variant"
    try:
        mi.set_variant("llvm_ad_rgb")
    except Exception as exc:  # noqa: BLE001 - a missing libLLVM shows up here in many forms
        return f"llvm_ad_rgb unavailable ({type(exc).__name__}: {exc}); Dr.Jit needs libLLVM (DRJIT_LIBLLVM_PATH)"
    return None


def mitsuba_step(work: Workload) -> Callable[[], tuple[float, float]]:
    """The same renders with Mitsuba 3 (``llvm_ad_rgb``, the ``direct`` integrator at 1 sample per
    pixel, a directional light following the camera, diffuse parts), forward and backward to the
    vertex positions. One scene of 9 part meshes is built once, as a training loop would keep it;
    each render loads its vertex positions and camera from torch into it, renders, back-propagates
    the MSE loss and reads the vertex gradients back into torch."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    faces = mi.UInt32(work.faces.flatten().numpy().astype(np.uint32))
    nparts, nverts = work.parts.shape[1:3]
    views = [mi.ScalarTransform4f().look_at(origin=eye.tolist(), target=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0])
             for eye in work.camera.center.double().numpy()]
    scene = {"type": "scene", "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
             "sensor": {"type": "perspective", "fov": FOV, "fov_axis": "y", "to_world": views[0],
                        "film": {"type": "hdrfilm", "width": work.size, "height": work.size,
                                 "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                        "sampler": {"type": "independent", "sample_count": 1}},
             # Shines along its local +Z, which to_world turns into the camera's viewing direction.
             "light": {"type": "directional", "to_world": views[0], "irradiance": 0.6 * math.pi}}
    for k in range(nparts):
        props = mi.Properties()
        reflectance = {"type": "rgb", "value": work.albedo[k].tolist()}
        props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": reflectance})
        mesh = mi.Mesh(f"part{k}", nverts, work.faces.shape[0], props=props, has_vertex_normals=True)
        mp = mi.traverse(mesh)
        mp["vertex_positions"] = mi.Float(work.parts[0, k].flatten().numpy())
        mp["faces"] = faces
        mp.update()
        scene[f"part{k}"] = mesh
    scene = mi.load_dict(scene)
    params = mi.traverse(scene)
    keys = [f"part{k}.vertex_positions" for k in range(nparts)]
    transforms = [mi.Transform4f(v) for v in views]
    targets = [mi.TensorXf(work.target[i].permute(1, 2, 0).contiguous().numpy()) for i in range(len(views))]

    def step() -> tuple[float, float]:
        fwd = bwd = 0.0
        verts = work.parts.numpy()
        for i in range(len(views)):
            t0 = time.perf_counter()
            for k, key in enumerate(keys):
                params[key] = mi.Float(verts[i, k].ravel())
                dr.enable_grad(params[key])
            params["sensor.to_world"] = transforms[i]
            params["light.to_world"] = transforms[i]
            params.update()
            image = mi.render(scene, params, spp=1, seed=0)  # a new seed per call would recompile the kernels
            loss = dr.mean(dr.square(image - targets[i]), axis=None)
            dr.eval(loss)
            t1 = time.perf_counter()
            dr.backward(loss)
            grads = [dr.grad(params[key]) for key in keys]
            dr.eval(*grads)
            grad = torch.from_numpy(np.concatenate([g.numpy() for g in grads]))  # back to torch, as training would
            t2 = time.perf_counter()
            if not torch.isfinite(grad).all():
                raise RuntimeError("mitsuba produced non-finite gradients")
            fwd, bwd = fwd + t1 - t0, bwd + t2 - t1
        return fwd, bwd

    return step


# --------------------------------------------------------------------------------------------- report
def verdict(ok: bool) -> str:
    return "PASS" if ok else "MISS"


HEADER = (f"{'size':>4}  {'backend':<8} {'ms/batch':>9} {'min ms':>8} {'fwd ms':>8} {'bwd ms':>8} {'x CNN step':>10}  "
          f"{'target':<22} result")


def report_row(rows: list[dict], size: int, name: str, timing: Timing, ratio: float, target: str = "",
               result: str = "") -> None:
    """Print one table row and keep it (with the raw samples) for the JSON output."""
    rows.append(dict(size=size, backend=name, ms=timing.total_ms, min_ms=timing.min_ms, forward_ms=timing.forward_ms,
                     backward_ms=timing.backward_ms, ratio=ratio, target=target or None, result=result or None,
                     samples_ms=timing.samples_ms))
    print(f"{size:>4}  {name:<8} {timing.total_ms:>9.1f} {timing.min_ms:>8.1f} {timing.forward_ms:>8.1f} "
          f"{timing.backward_ms:>8.1f} {ratio:>10.3f}  {target:<22} {result}")


def run(args: argparse.Namespace) -> dict:
    torch.set_num_threads(args.threads)
    installed = available_renderers()
    wanted = args.backends or installed + ["mitsuba"]
    missing = [b for b in wanted if b != "mitsuba" and b not in installed]
    if missing:
        raise SystemExit(f"backend(s) {missing} not installed; installed: {installed} (see `cerberus renderers`)")
    model, model_note = resnet10_model()
    mitsuba_note = mitsuba_status() if "mitsuba" in wanted else "not requested"
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    renders = QUADRUPLETS * IMAGES * VIEWPOINTS
    print(f"Render workload: {renders} renders/batch ({QUADRUPLETS} quadruplets x {IMAGES} images x {VIEWPOINTS} "
          "viewpoints), 9 parts x 320 faces, forward + backward (MSE loss)")
    print(f"CNN step: {model_note}; {CNN_IMAGES} images, forward + backward + Adam")
    print(f"ms/batch: median of {args.repeats} after {args.warmup} warm-up (min ms: the fastest); "
          f"torch threads {torch.get_num_threads()}; CPU cores {os.cpu_count()}; load average at start {load:.1f}")
    print(f"mitsuba: {mitsuba_note or f'llvm_ad_rgb, direct integrator, 1 spp, median of {args.mitsuba_repeats}'}\n")
    print(HEADER)
    print("-" * len(HEADER))
    rows: list[dict] = []
    for size in args.sizes:
        work = training_batch(size)
        cnn = time_split(cnn_step(size, model), args.repeats, args.warmup)
        report_row(rows, size, "cnn-step", cnn, 1.0)
        times = {}
        for name in wanted:
            if name == "mitsuba":
                if mitsuba_note:
                    print(f"{size:>4}  {'mitsuba':<8} {'skipped':>9}  ({mitsuba_note})")
                    continue
                timing = time_split(mitsuba_step(work), args.mitsuba_repeats, max(args.warmup, 1))
            else:
                timing = time_split(renderer_step(name, work), args.repeats, args.warmup)
            times[name] = timing.total_ms
            ratio = timing.total_ms / cnn.total_ms
            limit = TARGETS.get(name)
            if limit is None:
                report_row(rows, size, name, timing, ratio, "(reference only)")
            else:
                report_row(rows, size, name, timing, ratio, f"<= {limit} x CNN step", verdict(ratio <= limit))
        if "warp" in times and "torch" in times:
            speedup = times["torch"] / times["warp"]
            ok = speedup >= WARP_SPEEDUP
            rows.append(dict(size=size, backend="warp-vs-torch", speedup=speedup, target=f">= {WARP_SPEEDUP:g}x",
                             result=verdict(ok)))
            claim, goal = f"warp vs torch: {speedup:.1f}x faster", f">= {WARP_SPEEDUP:g}x faster"
            print(f"{size:>4}  {claim:<57}  {goal:<22} {verdict(ok)}")
    return dict(workload=dict(renders=renders, parts=9, faces_per_part=320, cnn_images=CNN_IMAGES, cnn=model_note,
                              repeats=args.repeats, warmup=args.warmup, threads=torch.get_num_threads(),
                              load_average=load, mitsuba=mitsuba_note or "ok"),
                rows=rows)


def write_json(result: dict, path: Path) -> None:
    """Write atomically: a temporary file in the same folder, then rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".json.tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(result, f, indent=2)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="Targets (2-core CPU): warp <= 0.1 x CNN step and >= 10x faster than torch; "
                                "torch <= 0.5 x CNN step. Mitsuba is timed for reference when installed.")
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 128], help="image sizes in pixels (default: 64 128)")
    p.add_argument("--repeats", type=int, default=5,
                   help="timed repeats per measurement; the median is shown (default: 5)")
    p.add_argument("--warmup", type=int, default=1, help="untimed runs first (kernel compilation, caches; default: 1)")
    p.add_argument("--backends", nargs="+", help="renderer backends to time, 'mitsuba' included "
                   "(default: every installed backend, then mitsuba if installed)")
    p.add_argument("--mitsuba-repeats", type=int, default=1, help="timed repeats for Mitsuba, which takes "
                   "tens of seconds per batch (default: 1, after one warm-up that compiles its kernels)")
    p.add_argument("--threads", type=int, default=torch.get_num_threads(), help="torch intra-op threads "
                   "(default: torch's default, %(default)s here)")
    p.add_argument("--json", type=Path, metavar="OUT", help="also write the results as JSON to OUT")
    args = p.parse_args(argv)
    if args.repeats < 1 or args.mitsuba_repeats < 1 or args.warmup < 0 or any(s < 8 for s in args.sizes):
        p.error("--repeats and --mitsuba-repeats must be >= 1, --warmup >= 0 and every size >= 8")
    result = run(args)
    if args.json:
        write_json(result, args.json)
        print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
