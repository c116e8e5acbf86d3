"""``cerberus reconstruct``: part meshes and pictures from images with a trained model."""
from __future__ import annotations

import argparse
from pathlib import Path

import torch

from cerberus_core.cli.checks import finite_float, output_folder
from cerberus_core.devices import check_device
from cerberus_core.errors import ConfigError
from cerberus_core.plugins import make_renderer


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reconstruct", help="3D part meshes (GLB, OBJ) and pictures from one or more images",
        description="Run a trained model on images. For each image writes the posed part meshes as one GLB (parts "
        "as named nodes, each a distinct colour) and OBJ files, and PNGs: the input, the reconstruction, the parts "
        "in colours, a turntable, a new lighting direction, and a new pose (this image's parts posed with the "
        "rotations and translations predicted from the next image), and index.html, an interactive 3D viewer of "
        "them that works offline. Images of another size are centre-cropped and resized (with a warning); an alpha "
        "channel is composited over the training background.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  cerberus reconstruct --model human person.png          # a shipped model (cerberus models)\n"
        "  cerberus reconstruct runs/cpu a.png b.png --out recon/   # your own run")
    p.add_argument("inputs", type=Path, nargs="+", metavar="[RUN] IMAGE",
                   help="a run folder, model.safetensors or checkpoint .pt (unless --model is given), then the input "
                   "image files (PNG, JPEG, ...)")
    p.add_argument("--model", help="a shipped pretrained model instead of a run (see `cerberus models`), e.g. human")
    p.add_argument("--viewer-images", type=int, default=12, metavar="N",
                   help="images in the interactive 3D viewer OUT/index.html (default: the first 12; 0: no viewer)")
    p.add_argument("--out", type=Path, default=Path("out/reconstruct"), help="output folder (default: out/reconstruct)")
    p.add_argument("--data", type=Path, help="dataset whose scene set-up (camera elevation, distance, fov, light) "
                   "the images follow (default: the set-up the run recorded, else the run's training data)")
    p.add_argument("--azimuth", type=finite_float, default=0.0,
                   help="camera azimuth assumed for the inputs, degrees (default 0; it only fixes the world frame)")
    p.add_argument("--renderer", help="renderer backend for the pictures (default: the run's)")
    p.add_argument("--device", default="cpu", help="device for the model (default: cpu)")
    p.set_defaults(func=run)


def output_names(paths: list[Path]) -> list[str]:
    """One distinct output name per input: the file stem, made unique with the parent folder's name and
    then a counter when stems repeat (``a/x.png b/x.png`` → ``a_x``, ``b_x``)."""
    stems = [p.stem or "image" for p in paths]
    counts = {s: stems.count(s) for s in stems}
    names = [s if counts[s] == 1 else f"{p.resolve().parent.name or 'root'}_{s}" for p, s in zip(paths, stems,
                                                                                                      strict=True)]
    seen: set[str] = set()
    out = []
    for name in names:
        unique, k = name, 2
        while unique in seen:
            unique, k = f"{name}_{k}", k + 1
        seen.add(unique)
        out.append(unique)
    return out


def run(args: argparse.Namespace) -> int:
    from cerberus_core.eval.export import export_reconstruction
    from cerberus_core.eval.figures import save_image_pictures
    from cerberus_core.eval.images import load_images
    from cerberus_core.eval.viewer import write_reconstruction_viewer
    from cerberus_core.lock import folder_lock
    from cerberus_core.train.checkpoint import load_run, model_scene

    # Every argument checked, the model, scene and images loaded, before anything is written.
    if args.model is not None:
        args.run, args.images = args.model, list(args.inputs)
    elif len(args.inputs) < 2:
        raise ConfigError("give a run folder (or --model NAME) and at least one image, e.g. "
                          "`cerberus reconstruct --model human photo.png`")
    else:
        args.run, args.images = args.inputs[0], list(args.inputs[1:])
    if args.viewer_images < 0:
        raise ConfigError(f"--viewer-images {args.viewer_images}: must be >= 0 (0: no viewer)")
    check_device(args.device)
    out = output_folder(args.out)
    model, config, saved_scene = load_run(args.run, args.device)
    scene = model_scene(config, args.data, saved_scene)
    size = int(config.data.image_size or 64)
    images, _ = load_images(args.images, size, scene.background)
    renderer = make_renderer(args.renderer or config.renderer)
    stems = output_names(list(args.images))
    camera = scene.cameras([args.azimuth] * len(images), size)
    with torch.no_grad():
        recon = model.reconstruct(images.to(args.device), camera.to(args.device)).to("cpu")
    with folder_lock(out, "cerberus reconstruct"):
        written = export_reconstruction(recon, out, stems)
        for i, stem in enumerate(stems):
            donor = recon.index([(i + 1) % len(stems)]) if len(stems) > 1 else None
            written += save_image_pictures(renderer, images[i], recon.index([i]), camera.index([i]),
                                           out, stem, pose_donor=donor, background=scene.background)
        written += write_reconstruction_viewer(out, images, recon, camera, stems, limit=args.viewer_images,
                                               limit_hint="--viewer-images", title=f"cerberus reconstruct: {args.run}",
                                               background=scene.background)
    renamed = [f"{p} -> {s}" for p, s in zip(args.images, stems, strict=True) if p.stem != s]
    if renamed:
        print("same-named inputs written under distinct names: " + ", ".join(renamed))
    print(f"wrote {len(set(written))} files for {len(stems)} image(s) to {out}")
    if args.viewer_images > 0:
        print(f"3D viewer: {out / 'index.html'}")
    return 0
