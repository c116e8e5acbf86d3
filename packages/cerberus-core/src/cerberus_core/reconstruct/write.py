"""Reconstruction of image files with a trained model: the implementation of
:meth:`cerberus_core.run.Run.reconstruct_images` (what ``cerberus reconstruct`` does; the one way in).

For each image: the posed part meshes (GLB, OBJ), the pictures of the paper's Figure 1 and a card of the
offline 3D viewer, all written into one result folder that replaces ``out`` only once everything is
written (:func:`cerberus_core.plumbing.outputs.writing_results`). Inputs out of the training domain are named
(:mod:`cerberus_core.reconstruct.input_domain`), and every input keeps its own output names
(:func:`output_names`).
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import torch

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import ConfigError
from cerberus_core.eval.export import export_reconstruction
from cerberus_core.eval.figures import PictureStyle, save_image_pictures
from cerberus_core.eval.viewer import CardDetails, ViewerPage, write_reconstruction_viewer
from cerberus_core.model.cerberus import Cerberus
from cerberus_core.parts import pose_donors
from cerberus_core.photo_mask import silhouette_ious, write_mask_pictures
from cerberus_core.plumbing.names import printable, safe_stem
from cerberus_core.plumbing.outputs import MARKER, resolved, writing_results
from cerberus_core.reconstruct.fit import FIT_STEPS, FitSettings, fit_silhouettes
from cerberus_core.reconstruct.images import LoadedImage
from cerberus_core.reconstruct.input_domain import domain_note, prepare_input
from cerberus_core.render.backends import make_renderer

#: Every name ``reconstruct`` writes for an image whose outputs are named ``STEM`` (meshes of
#: :func:`cerberus_core.eval.export.export_reconstruction`, pictures of
#: :func:`cerberus_core.eval.figures.save_image_pictures`, the viewer's new-pose GLB), and the names
#: of the folder itself. :func:`output_names` keeps every image's set apart from every other's.
OUTPUT_PATTERNS = ("{}.glb", "{}.obj", "{}_parts", "{}_input.png", "{}_reconstruction.png", "{}_parts.png",
                   "{}_new_lighting.png", "{}_new_pose.png", "{}_turntable.png", "{}_figure1.png",
                   "{}_new_pose.glb", "{}_mask.png", "{}_steps.png")
FOLDER_NAMES = ("index.html", MARKER)


def _outputs(stem: str) -> list[str]:
    return [pattern.format(stem) for pattern in OUTPUT_PATTERNS]


def output_names(paths: Sequence[Path]) -> list[str]:
    """One output name per input, such that no two inputs' files share a name.

    The name is the file stem made safe (:func:`cerberus_core.plumbing.names.safe_stem`: valid UTF-8, no control
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
    names = [s if counts[s.casefold()] == 1 else safe_stem(f"{resolved(p, 'images').parent.name or 'root'}_{s}")
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
    """The mask of each image: ``None`` each without ``masks``; one per image, in order; or, for one
    folder, ``FOLDER/<image stem>.png``."""
    if not masks:
        return [None] * len(images)
    if len(masks) == 1 and masks[0].is_dir():
        return [masks[0] / f"{Path(p).stem}.png" for p in images]
    if len(masks) != len(images):
        raise ConfigError.about("masks", None, f"{len(masks)} given for {len(images)} image(s); give one mask per "
                                "image, in the images' order, or one folder holding NAME.png for each image NAME")
    return list(masks)


def load_inputs(paths: Sequence[Path], masks: Sequence[Path | str | None], size: int, scene,
                kind: str | None = None, look: str = "shaded") -> tuple[torch.Tensor, list[str], list[LoadedImage]]:
    """The model's input images, per image its out-of-domain note (``""`` when in domain), and each one as
    loaded (its silhouette, if any); one warning names the images out of the training domain and the fix.
    ``masks``: a file, ``"auto"`` or ``None`` per image; ``kind``: the bodies the model learned; ``look``: the input
    look it learned (:func:`~cerberus_core.reconstruct.input_domain.prepare_input`)."""
    loaded = [prepare_input(p, size, scene, m, kind=kind, look=look) for p, m in zip(paths, masks, strict=True)]
    out = [(li, m) for li, m in zip(loaded, masks, strict=True) if li.out_of_domain]
    if out:
        shown = [printable(li.path.name) for li, _ in out[:3]]
        shown = [f"{n[:40]}...{n[-20:]}" if len(n) > 64 else n for n in shown]  # a 300-character name: its ends
        named = "; ".join(f"{n}: {li.out_of_domain}" for n, (li, _) in zip(shown, out, strict=False))
        more = f" (and {len(out) - 3} more)" if len(out) > 3 else ""
        fix = "; ".join(dict.fromkeys(li.advice for li, _ in out if li.advice))
        warnings.warn(f"{len(out)} of {len(loaded)} image(s) are out of the training domain, so their reconstructions "
                      f"are unreliable: {named}{more}; {fix}", UserWarning, stacklevel=1)
    return torch.stack([li.image for li in loaded]), [domain_note(li) for li in loaded], loaded


def borrowed_pose_notes(stems: Sequence[str], notes: Sequence[str], donors: Sequence[int | None]) -> list[str]:
    """Per image, ``""`` or the note that its new pose (Figure 1 (f)) borrows the pose of an image out of the
    training domain (``notes[donors[i]]`` not empty: no other image was in it,
    :func:`~cerberus_core.parts.pose_donors`); one warning names those images."""
    out = [f"(f) New Pose borrows the pose of {stems[j]}, which is out of the training domain"
           if j is not None and notes[j] else "" for j in donors]
    named = [f"{printable(stems[i])} from {printable(stems[j])}" for i, j in enumerate(donors) if out[i]]
    if named:
        more = f" (and {len(named) - 3} more)" if len(named) > 3 else ""
        warnings.warn(f"the new pose of {len(named)} image(s) borrows the pose of an out-of-domain image, as no "
                      f"other image is in the domain: {', '.join(named[:3])}{more}; add an image of a whole body on "
                      "the training background to lend a reliable pose", UserWarning, stacklevel=2)
    return out


@dataclass
class Reconstruction:
    """What :func:`write_reconstructions` wrote.

    Attributes:
        out: the result folder.
        stems: each input's output name (:func:`output_names`).
        written: the files written, relative to ``out``.
        renamed: ``"INPUT -> NAME"`` for inputs whose outputs could not take the input's own name.
        notes: each input's out-of-domain note (``""`` when in the training domain).
        silhouette_ious: per input, how well the reconstruction's rendered silhouette covers its mask or alpha
            (:func:`cerberus_core.photo_mask.silhouette_ious`; NaN when both are empty); ``None`` for an input
            without one.
        network_ious: the same for the network's prediction before it was fitted to the silhouettes
            (:mod:`cerberus_core.reconstruct.fit`); equal to ``silhouette_ious`` when nothing was fitted.
        fit_steps: the steps of that fit (0: none).
    """

    out: Path
    stems: list[str]
    written: list[str]
    renamed: list[str]
    notes: list[str]
    silhouette_ious: list[float | None]
    network_ious: list[float | None]
    fit_steps: int = 0

    def lines(self, viewer: bool) -> list[str]:
        """What ``cerberus reconstruct`` prints."""
        lines = ["inputs whose outputs would share or could not take their own name, written as: " +
                 ", ".join(self.renamed)] if self.renamed else []
        scored = [(s, v, n) for s, v, n in zip(self.stems, self.silhouette_ious, self.network_ious, strict=True)
                  if v is not None]
        if scored:
            fitted = self.fit_steps > 0
            shown = ", ".join(f"{printable(s)} {v:.3f}" + (f" (network {n:.3f})" if fitted else "")
                              for s, v, n in scored[:6]) + (" ..." if len(scored) > 6 else "")
            how = f" after fitting it to the mask for {self.fit_steps} steps" if fitted else ""
            lines.append(f"silhouette IoU of the reconstruction against the mask{how}: {shown}")
        lines.append(f"wrote {len(set(self.written))} files for {len(self.stems)} image(s) to {printable(self.out)}")
        return lines + ([f"3D viewer: {printable(self.out / 'index.html')}"] if viewer else [])


@dataclass(frozen=True)
class TrainedModel:
    """A trained model as :func:`write_reconstructions` uses it (:meth:`Run.reconstruct_images
    <cerberus_core.run.Run.reconstruct_images>` makes it from the run).

    Attributes:
        model: the model (on ``device``, in eval mode).
        scene: the scene set-up the images follow (camera elevation, distance, fov; background).
        image_size: the model's input size in pixels.
        renderer: the backend for the pictures (a name, :func:`~cerberus_core.render.backends.make_renderer`).
        device: where the model is.
        kind: the kind of bodies the model learned (a body source's name, :meth:`Run.training_kind
            <cerberus_core.run.Run.training_kind>`; ``None``: unknown), for the out-of-domain notes.
        look: the input look the model learned (``data.input_look``): its inputs are shown in it.
    """

    model: Cerberus
    scene: SceneSetup
    image_size: int
    renderer: str
    device: str | torch.device = "cpu"
    kind: str | None = None
    look: str = "shaded"


@dataclass(frozen=True)
class ImageInputs:
    """Image files to reconstruct (:func:`write_reconstructions`).

    Attributes:
        images: the input files; masks: each one's mask (``None``: none; default none for every image).
        azimuth: the camera azimuth assumed for every input, degrees.
    """

    images: Sequence[Path]
    masks: Sequence[Path | str | None] | None = None
    azimuth: float = 0.0


def write_reconstructions(trained: TrainedModel, inputs: ImageInputs, out: Path,
                          page: ViewerPage | None = None, fit: int = FIT_STEPS) -> Reconstruction:
    """Reconstruct image files and write the result folder ``out`` (checked by the caller with
    :func:`cerberus_core.plumbing.outputs.check_output`; replaced whole once everything is written).

    Args:
        trained: the model, its scene set-up, input size, renderer and device (:class:`TrainedModel`).
        inputs: the files, their masks (a file, ``"auto"``: the photo extra's person mask, or ``None`` per image)
            and the azimuth assumed (:class:`ImageInputs`).
        page: the viewer ``out/index.html``: title, ``limit`` of cards (0: no viewer), part labels
            (:class:`~cerberus_core.eval.viewer.ViewerPage`; its background is the scene's).
        fit: steps of fitting each reconstruction that has a silhouette (a mask, ``"auto"``, an alpha channel) to
            it after the network's prediction (:func:`~cerberus_core.reconstruct.fit.fit_silhouettes`; 0: none).
    """
    model, scene, image_size, device = trained.model, trained.scene, trained.image_size, trained.device
    images, azimuth = list(inputs.images), inputs.azimuth
    masks = list(inputs.masks) if inputs.masks is not None else [None] * len(images)
    pictures, notes, loaded = load_inputs(images, masks, image_size, scene, trained.kind, trained.look)
    backend = make_renderer(trained.renderer)
    stems = output_names(list(images))
    camera = scene.cameras([azimuth] * len(pictures), image_size)
    with torch.no_grad():
        recon = model.reconstruct(pictures.to(device), camera.to(device)).to("cpu")
    silhouettes = [li.silhouette for li in loaded]
    fitted = fit > 0 and any(s is not None for s in silhouettes)
    network_ious = silhouette_ious(backend, recon, camera, silhouettes) if fitted else None  # else: the ones below
    if fitted:
        recon = fit_silhouettes(backend, recon, camera, silhouettes, model.dihedral.cpu(), FitSettings(steps=fit))
    donors = pose_donors(len(stems), [bool(n) for n in notes])
    borrowed = borrowed_pose_notes(stems, notes, donors)
    with writing_results(out, "reconstruct") as tmp:  # out is replaced only once all is written
        written = export_reconstruction(recon, tmp, stems)
        for i, stem in enumerate(stems):
            donor = None if donors[i] is None else recon.index([donors[i]])
            note = "; ".join(n for n in (notes[i], borrowed[i]) if n)
            written += save_image_pictures(PictureStyle(backend, scene.background), pictures[i], recon.index([i]),
                                           camera.index([i]), tmp, stem, pose_donor=donor, note=note)
        masked, ious = write_mask_pictures(backend, recon, camera, loaded, stems, tmp, scene.background, network_ious)
        written += masked
        written += write_reconstruction_viewer(tmp, pictures, recon, camera, stems,
                                               replace(page or ViewerPage(), background=scene.background),
                                               CardDetails(notes=notes))
    renamed = [f"{printable(p)} -> {s}" for p, s in zip(images, stems, strict=True) if Path(p).stem != s]
    return Reconstruction(out, stems, written, renamed, notes, ious, ious if network_ious is None else network_ious,
                          fit if fitted else 0)
