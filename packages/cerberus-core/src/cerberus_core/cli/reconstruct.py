"""``cerberus reconstruct``: part meshes and pictures from images with a trained model."""
from __future__ import annotations

import argparse
import warnings
from collections.abc import Sequence
from pathlib import Path

import torch

from cerberus_core.cli.checks import RESULT_MARKER, finite_float, result_folder, writing_results
from cerberus_core.devices import check_device
from cerberus_core.errors import ConfigError
from cerberus_core.names import printable, safe_stem
from cerberus_core.plugins import make_renderer

#: Every name ``reconstruct`` writes for an image whose outputs are named ``STEM`` (meshes of
#: :func:`cerberus_core.eval.export.export_reconstruction`, pictures of
#: :func:`cerberus_core.eval.figures.save_image_pictures`, the viewer's new-pose GLB), and the names
#: of the folder itself. :func:`output_names` keeps every image's set apart from every other's.
OUTPUT_PATTERNS = ("{}.glb", "{}.obj", "{}_parts", "{}_input.png", "{}_reconstruction.png", "{}_parts.png",
                   "{}_new_lighting.png", "{}_new_pose.png", "{}_turntable.png", "{}_figure1.png",
                   "{}_new_pose.glb")
FOLDER_NAMES = ("index.html", RESULT_MARKER)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reconstruct", help="3D part meshes (GLB, OBJ) and pictures from one or more images",
        description="Run a trained model on images. For each image writes the posed part meshes as one GLB (parts "
        "as named nodes, each a distinct colour) and OBJ files, and PNGs: the input, the reconstruction, the parts "
        "in colours, a turntable, a new lighting direction, and a new pose (this image's parts posed with the "
        "rotations and translations predicted from the next image), and index.html, an interactive 3D viewer of "
        "them that works offline. Images of another size are centre-cropped and resized (with a warning).\n\n"
        "The model knows one whole body on the training background (black for the default look), framed by the "
        "training camera. An RGBA cut-out's alpha channel, or a --mask image, is the body's silhouette: the body is "
        "composited onto the training background and framed like the training images. Without either, an image "
        "whose border does not look like the training background (a photo) is still reconstructed, with one "
        "warning naming the fix, and its figure and viewer card say it is out of the training domain; so is a "
        "body cut off by the image's edge (a portrait).\n\n"
        "The results replace --out whole, in one step, when they are all written: an error or Ctrl-C leaves --out "
        "as it was. --out may hold earlier results; a folder holding other files needs --overwrite, and one holding "
        "an input is refused.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  cerberus reconstruct --model human person.png          # a shipped model (cerberus models)\n"
        "  cerberus reconstruct runs/cpu a.png b.png --out recon/   # your own run\n"
        "  cerberus reconstruct ./human a.png                       # a run folder called human (not the model)\n"
        "  cerberus reconstruct --model human a.jpg --mask a_mask.png   # a photo and its silhouette\n"
        "  cerberus reconstruct --model human photos/*.jpg --mask masks/  # masks/<name>.png for each photo")
    p.add_argument("inputs", nargs="+", metavar="[RUN] IMAGE",
                   help="a run folder, model.safetensors or checkpoint .pt (unless --model is given), then the input "
                   "image files (PNG, JPEG, ...). A bare name that a shipped model has (human) is that model: "
                   "write a folder of that name as ./human")
    p.add_argument("--model", help="a shipped pretrained model instead of a run (see `cerberus models`), e.g. human; "
                   "always the shipped model, never a local folder of that name")
    p.add_argument("--mask", action="append", type=Path, metavar="MASK",
                   help="the body's silhouette: an image of the input's size, white on the body and black elsewhere "
                   "(or its alpha channel). Give it once per input image, in the same order, or once as a folder "
                   "holding NAME.png for each input NAME.jpg/.png. Without it, an RGBA input's alpha is used")
    p.add_argument("--viewer-images", type=int, default=12, metavar="N",
                   help="images in the interactive 3D viewer OUT/index.html (default: the first 12; 0: no viewer)")
    p.add_argument("--out", type=Path, default=Path("out/reconstruct"),
                   help="output folder, replaced whole (default: out/reconstruct)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace --out even when it holds files that are not earlier results (never an input)")
    p.add_argument("--data", type=Path, help="dataset whose scene set-up (camera elevation, distance, fov, light) "
                   "the images follow (default: the set-up the run recorded, else the run's training data)")
    p.add_argument("--azimuth", type=finite_float, default=0.0,
                   help="camera azimuth assumed for the inputs, degrees (default 0; it only fixes the world frame)")
    p.add_argument("--renderer", help="renderer backend for the pictures (default: the run's)")
    p.add_argument("--device", default="cpu", help="device for the model (default: cpu)")
    p.set_defaults(func=run)


def _outputs(stem: str) -> list[str]:
    return [pattern.format(stem) for pattern in OUTPUT_PATTERNS]


def output_names(paths: Sequence[Path]) -> list[str]:
    """One output name per input, such that no two inputs' files share a name.

    The name is the file stem made safe (:func:`cerberus_core.names.safe_stem`: valid UTF-8, no control
    characters, short enough for every derived name); stems that repeat get the parent folder's name
    (``a/x.png b/x.png`` → ``a_x``, ``b_x``). Names are then claimed shortest first, and one whose files
    (:data:`OUTPUT_PATTERNS`) would meet names already claimed gets a counter: ``x.png`` keeps ``x``
    and ``x_new_pose.png`` becomes ``x_new_pose_2``, since ``x`` writes ``x_new_pose.glb``. Names are
    compared without case, as case-insensitive file systems do.
    """
    stems = [safe_stem(Path(p).stem) for p in paths]
    counts: dict[str, int] = {}
    for s in stems:
        counts[s.casefold()] = counts.get(s.casefold(), 0) + 1
    names = [s if counts[s.casefold()] == 1 else safe_stem(f"{Path(p).resolve().parent.name or 'root'}_{s}")
             for p, s in zip(paths, stems, strict=True)]
    claimed = {n.casefold() for n in FOLDER_NAMES}
    out: list[str] = [""] * len(names)
    for i in sorted(range(len(names)), key=lambda i: (len(names[i]), i)):
        unique, k = names[i], 2
        while any(o.casefold() in claimed for o in _outputs(unique)):
            unique, k = f"{names[i]}_{k}", k + 1
        claimed.update(o.casefold() for o in _outputs(unique))
        out[i] = unique
    return out


def mask_paths(masks: Sequence[Path] | None, images: Sequence[Path]) -> list[Path | None]:
    """The ``--mask`` of each image: ``None`` each without ``--mask``; one per image, in order; or, for one
    folder, ``FOLDER/<image stem>.png``."""
    if not masks:
        return [None] * len(images)
    if len(masks) == 1 and masks[0].is_dir():
        return [masks[0] / f"{Path(p).stem}.png" for p in images]
    if len(masks) != len(images):
        raise ConfigError(f"--mask given {len(masks)} time(s) for {len(images)} image(s); give one mask per image, in "
                          "the images' order, or one folder holding NAME.png for each image NAME")
    return list(masks)


def load_inputs(paths: Sequence[Path], masks: Sequence[Path | None], size: int, scene) -> tuple[torch.Tensor, list[str]]:
    """The model's input images and, per image, its out-of-domain note (``""`` when in domain); one warning
    names the images out of the training domain and the fix."""
    from cerberus_core.eval.input_domain import domain_note, prepare_input

    loaded = [prepare_input(p, size, scene, m) for p, m in zip(paths, masks, strict=True)]
    out = [(li, m) for li, m in zip(loaded, masks, strict=True) if li.out_of_domain]
    if out:
        shown = [printable(li.path.name) for li, _ in out[:3]]
        shown = [f"{n[:40]}...{n[-20:]}" if len(n) > 64 else n for n in shown]  # a 300-character name: its ends
        named = "; ".join(f"{n}: {li.out_of_domain}" for n, (li, _) in zip(shown, out, strict=False))
        more = f" (and {len(out) - 3} more)" if len(out) > 3 else ""
        fix = ("give an RGBA cut-out (transparent background) or --mask MASK.png (white on the body) for each"
               if any(m is None for _, m in out) else "give images of the whole body")
        warnings.warn(f"{len(out)} of {len(loaded)} image(s) are out of the training domain, so their reconstructions "
                      f"are unreliable: {named}{more}; {fix}", UserWarning, stacklevel=1)
    return torch.stack([li.image for li in loaded]), [domain_note(li) for li in loaded]


def run(args: argparse.Namespace) -> int:
    from cerberus_core.eval.export import export_reconstruction
    from cerberus_core.eval.figures import save_image_pictures
    from cerberus_core.eval.viewer import write_reconstruction_viewer
    from cerberus_core.train.checkpoint import load_run, looks_like_path, model_scene

    # Every argument checked, the model, scene and images loaded, before anything is written.
    if args.model is not None:
        if looks_like_path(args.model):
            raise ConfigError(f"--model {printable(args.model)}: takes a shipped model's name (see `cerberus "
                              "models`); give a run folder or model file as the first argument instead")
        from cerberus_core.zoo import model_path

        args.run, args.images = model_path(args.model), [Path(p) for p in args.inputs]
    elif len(args.inputs) < 2:
        raise ConfigError("give a run folder (or --model NAME) and at least one image, e.g. "
                          "`cerberus reconstruct --model human photo.png`")
    else:
        args.run, args.images = args.inputs[0], [Path(p) for p in args.inputs[1:]]
    if args.viewer_images < 0:
        raise ConfigError(f"--viewer-images {args.viewer_images}: must be >= 0 (0: no viewer)")
    check_device(args.device)
    masks = mask_paths(args.mask, args.images)
    keep = list(args.images) + [m for m in masks if m is not None] + ([Path(args.run)] if looks_like_path(args.run) else [])
    out = result_folder(args.out, overwrite=args.overwrite, keep=keep)
    model, config, saved_scene = load_run(args.run, args.device)
    scene = model_scene(config, args.data, saved_scene)
    size = int(config.data.image_size or 64)
    images, notes = load_inputs(args.images, masks, size, scene)
    renderer = make_renderer(args.renderer or config.renderer)
    stems = output_names(list(args.images))
    camera = scene.cameras([args.azimuth] * len(images), size)
    with torch.no_grad():
        recon = model.reconstruct(images.to(args.device), camera.to(args.device)).to("cpu")
    with writing_results(out, "cerberus reconstruct") as tmp:  # out is replaced only once all is written
        written = export_reconstruction(recon, tmp, stems)
        for i, stem in enumerate(stems):
            donor = recon.index([(i + 1) % len(stems)]) if len(stems) > 1 else None
            written += save_image_pictures(renderer, images[i], recon.index([i]), camera.index([i]),
                                           tmp, stem, pose_donor=donor, background=scene.background, note=notes[i])
        written += write_reconstruction_viewer(tmp, images, recon, camera, stems, limit=args.viewer_images, notes=notes,
                                               limit_hint="--viewer-images",
                                               title=f"cerberus reconstruct: {printable(args.model or args.run)}",
                                               background=scene.background)
    renamed = [f"{printable(p)} -> {s}" for p, s in zip(args.images, stems, strict=True) if p.stem != s]
    if renamed:
        print("inputs whose outputs would share or could not take their own name, written as: " + ", ".join(renamed))
    print(f"wrote {len(set(written))} files for {len(stems)} image(s) to {printable(out)}")
    if args.viewer_images > 0:
        print(f"3D viewer: {printable(out / 'index.html')}")
    return 0
