"""``cerberus reconstruct``: part meshes and pictures from images with a trained model."""
from __future__ import annotations

import argparse
from pathlib import Path

from cerberus_core.cli.checks import OVERWRITE_HELP
from cerberus_core.cli.flags import FlagNames
from cerberus_core.devices import check_device
from cerberus_core.errors import ConfigError
from cerberus_core.plumbing.names import printable


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus reconstruct`` (:data:`cerberus_core.cli.COMMANDS`)."""
    p.description = ("Run a trained model on images. For each image writes the posed part meshes as one GLB (parts "
        "as named nodes, each a distinct colour) and OBJ files, and PNGs: the input, the reconstruction, the parts "
        "in colours, a turntable, a new lighting direction, and a new pose (this image's parts posed with the "
        "rotations and translations predicted from the next image), and index.html, an interactive 3D viewer of "
        "them that works offline. Images of another size are centre-cropped and resized (with a warning).\n\n"
        "The model knows one whole body on the training background (black for the default look), framed by the "
        "training camera. An RGBA cut-out's alpha channel, or a --mask image, is the body's silhouette: the body is "
        "composited onto the training background and framed like the training images. Without either, an image "
        "whose border does not look like the training background (a photo) is still reconstructed, with one "
        "warning naming the fix, and its figure and viewer card say it is out of the training domain; so is a "
        "body cut off by the image's edge (a portrait). An image with a silhouette (a mask, --mask auto, an alpha "
        "channel) has its reconstruction fitted to it after the network's prediction (--fit: the parts' vertices and "
        "translations move until their outline matches the mask, held near the prediction; the depth stays the "
        "network's); the silhouette IoU of both is printed.\n\n"
        "The results replace --out whole, in one step, when they are all written: an error or Ctrl-C leaves --out "
        "as it was. --out may be new, empty or earlier results of cerberus reconstruct; a folder holding anything "
        "else (or an input) is refused, --overwrite or not (docs/outputs.md).")
    p.epilog = ("examples:\n  cerberus reconstruct --model human person.png          # a shipped model (cerberus models)\n"
        "  cerberus reconstruct runs/cpu a.png b.png --out recon/   # your own run\n"
        "  cerberus reconstruct ./human a.png                       # a run folder called human (not the model)\n"
        "  cerberus reconstruct --model human a.jpg --mask a_mask.png   # a photo and its silhouette\n"
        "  cerberus reconstruct --model human photos/*.jpg --mask masks/  # masks/<name>.png for each photo\n"
        "  cerberus reconstruct --model human photo.jpg --mask auto      # the person found by cerberus-core[photo]")
    p.add_argument("inputs", nargs="+", metavar="[RUN] IMAGE",
                   help="a run folder, model.safetensors or checkpoint .pt (unless --model is given), then the input "
                   "image files (PNG, JPEG, ...). A bare name that a shipped model has (human) is that model: "
                   "write a folder of that name as ./human")
    p.add_argument("--model", help="a shipped pretrained model instead of a run (see `cerberus models`), e.g. human; "
                   "always the shipped model, never a local folder of that name")
    p.add_argument("--mask", action="append", metavar="MASK",
                   help="the body's silhouette: an image of the input's size, white on the body and black elsewhere "
                   "(or its alpha channel). Give it once per input image, in the same order, or once as a folder "
                   "holding NAME.png for each input NAME.jpg/.png; or `--mask auto`: the person found in each image "
                   "by a segmentation model that ships in the optional extra cerberus-core[photo] (offline), the mask "
                   "written beside the result (NAME_mask.png, NAME_steps.png); a mask file named auto is ./auto. "
                   "Without it, an RGBA input's alpha is used")
    p.add_argument("--fit", type=int, default=argparse.SUPPRESS, metavar="STEPS",  # default: Run.reconstruct_images'
                   help="steps of fitting each reconstruction that has a silhouette to it (default 100, "
                   "cerberus_core.reconstruct.fit.FIT_STEPS, about 1.5 s per image; 0: the network's prediction as "
                   "it is). On the photo-like test the fit takes the outline's IoU against the mask from 0.76 to "
                   "0.92 and leaves the 3D voxel IoU where it was (docs/evaluation.md)")
    p.add_argument("--viewer-images", type=int, default=12, metavar="N",
                   help="images in the interactive 3D viewer OUT/index.html (default: the first 12; 0: no viewer)")
    p.add_argument("--out", type=Path, default=Path("out/reconstruct"),
                   help=f"output folder, replaced whole (default: out/reconstruct); {OVERWRITE_HELP}")
    p.add_argument("--overwrite", action="store_true",
                   help="accepted for older scripts and changes nothing: earlier results of cerberus reconstruct are "
                   "replaced without it, and nothing else ever is (docs/outputs.md)")
    p.add_argument("--data", type=Path, help="dataset whose scene set-up (camera elevation, distance, fov, light) "
                   "the images follow (default: the set-up the run recorded, else the run's training data)")
    p.add_argument("--azimuth", type=float, default=0.0,
                   help="camera azimuth assumed for the inputs, degrees (default 0; it only fixes the world frame)")
    p.add_argument("--renderer", help="renderer backend for the pictures (default: the run's)")
    p.add_argument("--device", default="cpu", help="device for the model (default: cpu)")
    # The flag of each setting of Run.load and Run.reconstruct_images (and an image's mask).
    p.set_defaults(func=run, flag_names=FlagNames({
        "masks": "--mask", "mask": "--mask", "viewer_images": "--viewer-images", "out": "--out",
        "data": "--data", "azimuth": "--azimuth", "renderer": "--renderer", "device": "--device", "fit": "--fit"}))


def run(args: argparse.Namespace) -> int:
    from cerberus_core.photo_mask import AUTO, require_segmenter
    from cerberus_core.run import Run
    from cerberus_core.weights import looks_like_path
    from cerberus_core.zoo import model_path

    if args.model is not None:
        if looks_like_path(args.model):
            raise ConfigError(f"--model {printable(args.model)}: takes a shipped model's name (see `cerberus "
                              "models`); give a run folder or model file as the first argument instead", key="model", value=args.model)
        model_path(args.model)  # a shipped model's name (ZooError naming the known ones otherwise)
        source, images = args.model, args.inputs  # by name: the shipped model, titled by its name
    elif len(args.inputs) < 2:
        raise ConfigError("give a run folder (or --model NAME) and at least one image, e.g. "
                          "`cerberus reconstruct --model human photo.png`", key="inputs")
    else:
        source, images = args.inputs[0], args.inputs[1:]
    check_device(args.device)
    auto = args.mask == [AUTO]  # as typed: a mask file named auto is ./auto
    if auto:
        require_segmenter()  # one line naming the extra, before the model is loaded
    masks = AUTO if auto else None if args.mask is None else [Path(m) for m in args.mask]
    result = Run.load(source, args.device).reconstruct_images(
        images, args.out, masks=masks, data=args.data, azimuth=args.azimuth,
        renderer=args.renderer, viewer_images=args.viewer_images, **({"fit": args.fit} if "fit" in args else {}))
    print("\n".join(result.lines(viewer=args.viewer_images > 0)))
    return 0
