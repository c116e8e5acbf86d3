"""Training speed: steps per second of each preset as ``cerberus train`` runs it, and the share of
each step spent rendering.

Every timed configuration (a preset with a renderer backend, or a speed-switch variant) runs in its
own worker process, which builds the trainer exactly as ``cerberus train`` does
(``cerberus_core.train.trainer._Trainer``: the preset's own ``speed:`` section, ``speed.autocast:
auto`` resolved for this machine, the model, the optimiser, the learning-rate schedule) on one
batch of the preset's batch size from a small ``primitives`` dataset rendered at the preset's
training resolution (generated into a temporary folder, or ``--data ROOT``), and times the
trainer's own step (``_Trainer._step``: objective, finiteness checks, backward, gradient norm,
clipping, Adam; then the scheduler). The parent interleaves the workers step by step, round by round
(the order reversed every other round), so a change of load hits every configuration alike and no
configuration runs in a process another has warmed, slowed or filled (a bfloat16 variant that the
CPU only emulates once left the variants timed after it several times slower). It prints the
median wall-clock time and the median CPU time of the worker process per step (with one thread,
the CPU time is what the step costs, less disturbed by other jobs), and the rendering share (the
step's render call alone, forward and backward, over the step's wall time).

    python benchmarks/bench_train.py                 # 1 thread, both presets, both backends
    python benchmarks/bench_train.py --threads 2 --steps 10 --renderers warp
    python benchmarks/bench_train.py --device cuda --renderers torch --steps 50 --warmup 10   # on a GPU
    python benchmarks/bench_train.py --switches --presets cpu --renderers warp --steps 20

``--switches [NAME ...]`` times the training speed switches instead (``speed.autocast: bf16``,
``speed.channels_last``, ``speed.compile``, ``speed.smoothness_once``; all of them without NAMEs):
one worker per variant (off, each switch alone, all together), with each variant's first-step loss
(same weights, same batch: they differ by rounding only). ``--precision`` times the preset with
``speed.autocast`` at ``null`` (float32), ``bf16`` and ``auto`` (its other switches as the preset has
them). ``--settings KEY=VALUE [...]`` times config settings the same way (the preset as it is, then
each setting alone on top; a KEY is a full config key as ``cerberus train --set`` takes it, its VALUE
parsed and validated as there): what a loss term or a model option beyond the preset adds to a step,
e.g. issue 30's limb terms:

    python benchmarks/bench_train.py \
        --settings losses.coverage=1.0 losses.keypoint_coverage=1.0 losses.overlap=0.1 losses.rotation=0.1 \
        --presets cpu --renderers warp --threads 1 --steps 8 --warmup 2 --data DATA

On a CPU without native bfloat16 ``--switches`` and ``--precision`` leave the ``bf16`` variants out
and say so (PyTorch emulates bfloat16 convolutions there, over ten times slower); ``--emulated-bf16``
times them anyway.

Every run starts with the machine's instruction set (torch's CPU capability, the CPU's vector and
bfloat16 flags) and what ``speed.autocast: auto`` resolves to here, and why. Timings on a shared
machine are noisy: the load average is printed with the results.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cerberus_core.datasets.dataset import Dataset

HERE = Path(__file__).resolve().parent


# ------------------------------------------------------------------ inside a worker process
def make_data(root: Path, image_size: int) -> Path:
    """A small ``primitives`` quadruplet dataset at ``image_size`` pixels in ``root``."""
    from dataclasses import replace

    from cerberus_core.datasets.dataset import Dataset
    from cerberus_core.datasets.plan import preset_config
    from cerberus_core.datasets.settings import SplitConfig

    cfg = preset_config("primitives", "tiny", image_size=image_size)
    cfg = replace(cfg, splits={"train": SplitConfig("pairs", subjects=2, pairs=16, meshes=False)})
    Dataset.generate(cfg, root, progress=False, log=lambda _: None)
    return root


def trainer_step(spec: dict):
    """The trainer of ``cerberus train`` for ``spec`` (preset, renderer, data, batch size, device,
    optional ``speed`` overrides, optional ``settings``: ``--set KEY=VALUE`` strings), built as
    :func:`cerberus_core.train.trainer.train` builds it, one batch on its device, and a function running
    the trainer's step ``i`` on that batch (then the scheduler's step) that returns the step's loss.

    Uses only what the trainer has had since before the speed work of issue 33 (``_Trainer(config,
    run_dir, info, device, dataset)``, ``_build``, ``_step``), so ``bench_revisions.py`` can time
    older revisions with it."""
    import dataclasses

    import torch

    from cerberus_core.train.data import quadruplet_batch
    from cerberus_core.train.distributed import init_distributed
    from cerberus_core.train.settings import load_config
    from cerberus_core.train.trainer import _Trainer

    if spec.get("settings"):  # as `cerberus train --set` applies them: parsed and validated by the loader
        cfg = load_config(preset=spec["preset"], overrides=spec["settings"])
    else:
        cfg = load_config(preset=spec["preset"])
    cfg.renderer = spec["renderer"]
    cfg.device = spec["device"]
    if spec.get("batch_size"):
        cfg.train.batch_size = spec["batch_size"]
    if spec.get("speed") is not None:
        cfg.speed = dataclasses.replace(cfg.speed, **spec["speed"])
    device = torch.device(spec["device"])
    data = Dataset.open(spec["data"]).quadruplets()
    trainer = _Trainer(cfg, Path(spec["run_dir"]), init_distributed(device), device, data)
    trainer._build(None)
    raw = torch.utils.data.default_collate([data[i % len(data)] for i in range(cfg.train.batch_size)])
    batch = quadruplet_batch(raw, device, trainer.scene, trainer.image_size)

    def step(i: int) -> float:
        _, out, _ = trainer._step(batch, i)
        trainer.scheduler.step()
        return float(out.total.detach())
    return trainer, batch, step


def render_seconds(trainer, batch, steps: int, sync) -> float:
    """Seconds of the step's render call alone (forward and backward of ``render_parts`` on the same
    scenes as the objective's, anti-aliased when the preset's ``render.antialias`` is on)."""
    import torch

    from cerberus_core.losses import viewpoint_scenes
    from cerberus_core.render.api import render_parts
    from cerberus_core.render.camera import Camera
    from cerberus_core.train.objective import partner_cameras

    cfg, model, scene = trainer.config, trainer.model, trainer.scene
    bsz, size = batch.num_quadruplets, batch.images.shape[-1]
    with torch.no_grad():
        pred = model(batch.images.flatten(0, 1))
        rot, trans, _, _ = model.world_pose(pred, batch.camera)
        n, v = pred.local_vertices.shape[1:3]
        own, cross = viewpoint_scenes(pred.local_vertices.view(bsz, 4, n, v, 3), rot.view(bsz, 4, n, 3, 3),
                                      trans.view(bsz, 4, n, 3))
    if cfg.losses.viewpoint_consistency:
        verts = torch.cat([own.flatten(0, 1), cross.flatten(0, 1)])
        cams = Camera.cat([batch.camera, partner_cameras(batch.camera, bsz)])
    else:
        verts, cams = own.flatten(0, 1), batch.camera
    verts.requires_grad_(True)
    grad = torch.rand(verts.shape[0], 3, size, size, device=verts.device)

    def render_once():
        img = render_parts(trainer.renderer, verts, model.faces, cams, scene.light(cams), albedo=scene.albedo,
                           background=scene.background, antialias=cfg.render.antialias).image
        img.backward(grad)

    render_once()
    sync()
    t0 = time.perf_counter()
    for _ in range(steps):
        render_once()
    sync()
    return (time.perf_counter() - t0) / steps


def worker(spec: dict) -> None:
    """Serve one configuration: build it, run the warm-up, then answer ``step`` / ``render`` / ``quit``
    requests (one JSON line each on stdin) with one JSON line on the original stdout (everything
    else the process prints goes to stderr)."""
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    import torch

    import cerberus_core

    torch.set_num_threads(spec["threads"])
    dev = torch.device(spec["device"])

    def sync() -> None:
        if dev.type == "cuda":
            torch.cuda.synchronize(dev)

    with tempfile.TemporaryDirectory() as tmp:
        spec["run_dir"] = str(Path(tmp) / "run")
        t0 = time.perf_counter()
        trainer, batch, step = trainer_step(spec)
        first = step(0)
        for i in range(1, spec["warmup"]):
            step(i)
        sync()
        cfg = trainer.config
        images = 4 * batch.num_quadruplets
        backend = sys.modules.get(type(trainer.renderer).__module__.split(".")[0])
        ready = {"first_loss": first, "warmup_s": time.perf_counter() - t0, "core": cerberus_core.__file__,
                 "backend": getattr(backend, "__file__", "?"), "renderer": cfg.renderer,
                 "speed": dataclass_dict(cfg.speed), "note": trainer.speed_note, "batch": batch.num_quadruplets,
                 "size": batch.images.shape[-1], "width": cfg.model.width, "images": images,
                 "renders": images * (2 if cfg.losses.viewpoint_consistency else 1),
                 "optimizer": optimizer_kind(trainer.optimizer)}
        proto.write(json.dumps(ready) + "\n")
        for line in sys.stdin:
            req = json.loads(line)
            if req["do"] == "step":
                sync()
                w0, c0 = time.perf_counter(), time.process_time()
                step(req["i"])
                sync()
                proto.write(json.dumps({"wall": time.perf_counter() - w0, "cpu": time.process_time() - c0}) + "\n")
            elif req["do"] == "render":
                proto.write(json.dumps({"render_s": render_seconds(trainer, batch, req["steps"], sync)}) + "\n")
            else:
                break


def dataclass_dict(obj) -> dict:
    import dataclasses

    return dataclasses.asdict(obj)


def optimizer_kind(opt) -> str:
    """How the optimiser runs its update: ``Adam(fused=True)``, or ``Adam(fused=None, foreach=None)``
    (torch's default: the per-parameter loop on the CPU, ``foreach`` on CUDA)."""
    group = opt.param_groups[0]
    return f"{type(opt).__name__}(fused={group.get('fused')}, foreach={group.get('foreach')})"


# ------------------------------------------------------------------ the parent: workers, interleaved
class Worker:
    """One configuration in its own process (:func:`worker`), driven over pipes."""

    def __init__(self, label: str, spec: dict, env: dict | None = None) -> None:
        self.label, self.spec, self.wall, self.cpu = label, spec, [], []
        code = f"import json, sys; sys.path.insert(0, {str(HERE)!r}); import bench_train; " \
               f"bench_train.worker(json.loads({json.dumps(spec)!r}))"
        threads = str(spec["threads"])
        self.proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True, env={**(env or os.environ), "OMP_NUM_THREADS": threads,
                                                     "MKL_NUM_THREADS": threads})
        self.info = self._read()

    def _read(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            self.proc.wait()
            sys.exit(f"bench_train: the worker for {self.label} failed (exit {self.proc.returncode}; its error is above)")
        return json.loads(line)

    def ask(self, **req) -> dict:
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        return self._read()

    def step(self, i: int) -> None:
        out = self.ask(do="step", i=i)
        self.wall.append(out["wall"])
        self.cpu.append(out["cpu"])

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write(json.dumps({"do": "quit"}) + "\n")
                self.proc.stdin.close()
            except BrokenPipeError:
                pass
            try:  # a loaded machine can take minutes to tear a training down; the timings are already in
                self.proc.wait(timeout=600)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    @property
    def wall_s(self) -> float:
        return statistics.median(self.wall)

    @property
    def cpu_s(self) -> float:
        return statistics.median(self.cpu)


def interleave(workers: list[Worker], rounds: int, first_step: int) -> None:
    """``rounds`` rounds of one step of every worker in turn, the order reversed every other round."""
    for r in range(rounds):
        for w in (workers if r % 2 == 0 else workers[::-1]):
            w.step(first_step + r)


def start(workers: list[tuple[str, dict, dict | None]]) -> list[Worker]:
    """Start the workers one after another (each compiles and warms up alone)."""
    out = []
    for label, spec, env in workers:
        print(f"  starting {label} ...", flush=True)
        out.append(Worker(label, spec, env))
    return out


def machine_lines(device: str = "cpu") -> list[str]:
    """The machine's instruction set and what ``speed.autocast: auto`` resolves to on it, and why."""
    import torch

    from cerberus_core.devices import NATIVE_BF16_FLAGS, cpu_flags
    from cerberus_core.train.speed import resolve_autocast

    model = next((line.split(":", 1)[1].strip() for line in _cpuinfo().splitlines()
                  if line.lower().startswith("model name")), "unknown CPU")
    have = sorted(f for f in cpu_flags() if f.startswith(("avx", "amx", "fma")) or f in NATIVE_BF16_FLAGS)
    picked, why = resolve_autocast("auto", device)
    return [f"machine: {model}, {os.cpu_count()} CPUs; torch {torch.__version__}, CPU capability "
            f"{torch.backends.cpu.get_cpu_capability()}",
            f"CPU flags: {' '.join(have) or 'none of avx/amx/fma/bf16'}",
            f"speed.autocast auto -> {picked or 'null (float32)'} ({why})"]


def _cpuinfo() -> str:
    try:
        return open("/proc/cpuinfo", encoding="ascii", errors="replace").read()
    except OSError:
        return ""


def load_line(args: argparse.Namespace, what: str) -> str:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"{args.threads} thread(s), load average {load:.1f} on {os.cpu_count()} CPUs; median of {args.steps} "
            f"interleaved rounds after {args.warmup} warm-up steps; {what}")


def base_spec(args: argparse.Namespace, preset: str, renderer: str, root: Path) -> dict:
    return {"preset": preset, "renderer": renderer, "data": str(root), "batch_size": args.batch_size,
            "device": args.device, "threads": args.threads, "warmup": args.warmup, "speed": None}


def dataset_for(args: argparse.Namespace, preset: str, tmp: Path) -> Path:
    """``--data``, or a ``primitives`` set at the preset's resolution generated under ``tmp`` (once per size)."""
    if args.data is not None:
        return args.data.resolve()
    from cerberus_core.train.settings import load_config

    size = load_config(preset=preset).data.image_size or 64
    root = tmp / f"prim{size}"
    if not root.exists():
        make_data(root, size)
    return root


SWITCHES = {"autocast": {"autocast": "bf16"}, "channels_last": {"channels_last": True}, "compile": {"compile": True},
            "smoothness_once": {"smoothness_once": True}}
"""``--switches`` names and the ``speed:`` settings (:mod:`cerberus_core.train.speed`) each one turns on."""

OFF = {"autocast": None, "channels_last": False, "compile": False, "smoothness_once": False}


def switch_variants(names: list[str]) -> list[tuple[str, dict]]:
    """``off``, each named switch alone, and (with two or more) all of them together."""
    variants = [("off", OFF)] + [(n, OFF | SWITCHES[n]) for n in names]
    if len(names) > 1:
        variants.append(("+".join(names), OFF | {k: v for n in names for k, v in SWITCHES[n].items()}))
    return variants


def precision_variants(preset: str) -> list[tuple[str, dict]]:
    """``fp32``, ``bf16`` and ``auto``: the preset's speed switches with ``speed.autocast`` set to each."""
    return [(label, {"autocast": value}) for label, value in (("fp32", None), ("bf16", "bf16"), ("auto", "auto"))]


def setting_variants(settings: list[str]) -> list[tuple[str, dict | None, list[str]]]:
    """For ``--settings``: the preset as it is, then each ``KEY=VALUE`` setting alone on top
    (``(label, speed settings, config overrides)``)."""
    return [("preset", None, [])] + [(f"+ {s}", None, [s]) for s in settings]


def check_settings(p: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """``--settings`` checked before any worker starts: each one loaded on each preset as ``cerberus train --set``
    loads it, so a bad key or value stops here with the config loader's message."""
    from cerberus_core.errors import ConfigError
    from cerberus_core.train.settings import load_config

    for s in args.settings:
        key = s.partition("=")[0].strip()
        if key in ("renderer", "device"):
            p.error(f"--settings {s}: give the {key} with --{key}{'s' if key == 'renderer' else ''}")
        for preset in args.presets:
            try:
                load_config(preset=preset, overrides=[s])
            except ConfigError as exc:
                p.error(f"--settings {s} (preset {preset}): {exc}")


def bf16_left_out(emulated: bool, device: str) -> bool:
    """Whether ``speed.autocast: bf16`` variants are left out here: on a CPU that would emulate
    bfloat16, unless ``emulated`` (said when they are)."""
    from cerberus_core.devices import native_bf16

    native, why = native_bf16(device)
    if native or emulated:
        return False
    print(f"left out: speed.autocast bf16: {why}; PyTorch's bfloat16 convolutions leave oneDNN there and run "
          "over ten times slower. --emulated-bf16 times it anyway, in a process of its own like every variant")
    return True


def run_switches(args: argparse.Namespace) -> None:
    """``--switches`` / ``--precision`` / ``--settings``: the variants side by side, one worker each,
    interleaved."""
    names = None if args.precision or args.settings else (args.switches or list(SWITCHES))
    if names and "compile" in names:
        args.warmup = max(args.warmup, 3)  # compilation, then its recompilation-free steady state
    rows = []
    drop = not args.settings and bf16_left_out(args.emulated_bf16, args.device)
    with tempfile.TemporaryDirectory() as tmp:
        for preset in args.presets:
            root = dataset_for(args, preset, Path(tmp))
            for name in args.renderers:
                if args.settings:
                    variants = setting_variants(args.settings)
                elif args.precision:
                    variants = [v for v in precision_variants(preset) if v[1]["autocast"] != "bf16" or not drop]
                else:
                    variants = switch_variants([n for n in names if n != "autocast" or not drop])
                specs = [(label, base_spec(args, preset, name, root)
                          | {"speed": speed, "settings": rest[0] if rest else []}, None)
                         for label, speed, *rest in variants]
                workers = start(specs)
                try:
                    interleave(workers, args.steps, args.warmup)
                finally:
                    for w in workers:
                        w.close()
                base = workers[0]
                rows += [{"preset": preset, "renderer": w.info["renderer"], "switches": w.label, "wall": w.wall_s,
                          "cpu": w.cpu_s, "speedup": base.wall_s / w.wall_s, "speedup_cpu": base.cpu_s / w.cpu_s,
                          "first_loss": w.info["first_loss"], "warmup_s": w.info["warmup_s"]} for w in workers]
    print()
    print("\n".join(machine_lines(args.device)))
    print(load_line(args, "each variant in its own process"))
    w = max(10, *(len(r["switches"]) + 2 for r in rows))
    base = rows[0]["switches"] if rows else "off"
    head = f"{'preset':<8}{'renderer':>9}  {'variant':<{w}}{'s/step':>8}{'CPU s':>8}{'x ' + base:>10}" \
           f"{'x ' + base + ' CPU':>{len(base) + 7}}" \
           f"{'loss 1st step':>15}{'warm-up s':>11}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['preset']:<8}{r['renderer']:>9}  {r['switches']:<{w}}{r['wall']:>8.3f}{r['cpu']:>8.3f}"
              f"{r['speedup']:>10.2f}{r['speedup_cpu']:>{len(base) + 7}.2f}{r['first_loss']:>15.7f}"
              f"{r['warmup_s']:>11.1f}")


def run_presets(args: argparse.Namespace) -> None:
    """The default table: each preset with each backend, as ``cerberus train`` runs it, interleaved."""
    with tempfile.TemporaryDirectory() as tmp:
        specs = [(f"{preset} / {name}", base_spec(args, preset, name, dataset_for(args, preset, Path(tmp))), None)
                 for preset in args.presets for name in args.renderers]
        workers = start(specs)
        try:
            interleave(workers, args.steps, args.warmup)
            for w in workers:
                w.render_s = w.ask(do="render", steps=max(1, args.steps // 2))["render_s"]
        finally:
            for w in workers:
                w.close()
    print()
    print("\n".join(machine_lines(args.device)))
    where = "CPU" if args.device == "cpu" else args.device
    print(load_line(args, f"{where}; each configuration in its own process, as `cerberus train` runs it"))
    for w in workers:
        print(f"  {w.label}: {w.info['note']}; speed {w.info['speed']}; {w.info['optimizer']}")
    head = f"{'preset':<16}{'renderer':>9}{'batch':>6}{'px':>5}{'width':>6}{'images':>7}{'renders':>8}{'s/step':>9}" \
           f"{'CPU s':>8}{'steps/s':>9}{'render s':>10}{'render %':>9}{'loss 1st step':>15}"
    print(head)
    print("-" * len(head))
    for w in workers:
        i = w.info
        print(f"{w.spec['preset']:<16}{i['renderer']:>9}{i['batch']:>6}{i['size']:>5}{i['width']:>6}{i['images']:>7}"
              f"{i['renders']:>8}{w.wall_s:>9.3f}{w.cpu_s:>8.3f}{1 / w.wall_s:>9.3f}{w.render_s:>10.3f}"
              f"{100 * w.render_s / w.wall_s:>8.1f}%{i['first_loss']:>15.7f}")
    by = {(w.spec["preset"], w.info["renderer"]): w for w in workers}
    first = args.presets[0]
    for (preset, renderer), w in by.items():
        if preset != first and (first, renderer) in by:
            print(f"{preset} step / {first} step ({renderer}): {w.wall_s / by[first, renderer].wall_s:.2f}x")
    for preset in args.presets:
        if (preset, "torch") in by and (preset, "warp") in by:
            print(f"{preset}: torch step / warp step = {by[preset, 'torch'].wall_s / by[preset, 'warp'].wall_s:.2f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--presets", nargs="+", default=["cpu", "paper"], help="training presets to time")
    p.add_argument("--renderers", nargs="+", default=["torch", "warp"],
                   help="renderer backends to time each preset with (default: torch warp; 'auto' as training picks)")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads per worker (default 1, as the cpu preset)")
    p.add_argument("--steps", type=int, default=10, help="timed rounds (one step of every worker each)")
    p.add_argument("--warmup", type=int, default=3, help="untimed steps first, per worker")
    p.add_argument("--batch-size", type=int, default=None, help="override the presets' batch sizes")
    p.add_argument("--data", type=Path, default=None, help="a quadruplet dataset (default: generate primitives)")
    p.add_argument("--device", default="cpu",
                   help="device of the timed steps: cpu (default) or cuda[:N] (the renderer follows the tensors)")
    p.add_argument("--precision", action="store_true",
                   help="instead: time speed.autocast null (fp32), bf16 and auto side by side, with the preset's "
                        "other speed switches")
    p.add_argument("--switches", nargs="*", default=None, choices=sorted(SWITCHES), metavar="NAME",
                   help="instead: time the speed switches (speed.* of the config) side by side: off, each NAME alone "
                        f"and all NAMEs together (default with no NAME: {' '.join(SWITCHES)})")
    p.add_argument("--settings", nargs="+", default=None, metavar="KEY=VALUE",
                   help="instead: time the preset, then each config setting alone on top, interleaved (full keys as "
                        "`cerberus train --set` takes them, e.g. losses.coverage=1.0 model.axis_scales=true)")
    p.add_argument("--emulated-bf16", action="store_true",
                   help="with --switches/--precision: time bf16 autocast even where the CPU only emulates bfloat16")
    args = p.parse_args()
    if args.settings:
        check_settings(p, args)
    if args.switches is not None or args.precision or args.settings:
        run_switches(args)
    else:
        run_presets(args)


if __name__ == "__main__":
    main()
