"""The Cerberus network: image → ``N`` posed part meshes (section 3 of the paper).

``Cerberus.forward(images)`` runs the down-sampling network, the up-sampling network and the three
heads and returns camera-independent :class:`Predictions`; :meth:`Cerberus.pose` places the parts
with the known camera (translation predicted relative to the camera, rotation relative to the camera or, with
``model.rotation: world``, to the world; both expressed in the world frame); :meth:`Cerberus.reconstruct` does
both and returns a :class:`~cerberus_core.parts.PartSet`.

Frames: a part's local vertices ``x`` (deformed sphere) map to the camera frame as
``R_cam x + T_cam`` and to the world as ``R_world x + T_world`` with ``R_world = R^T R_cam`` and
``T_world`` the world-space unprojection (``R``: the camera's world→camera rotation); the rotation head's matrix
is ``R_cam`` (``model.rotation: camera``, the paper) or ``R_world`` (``world``), and ``none`` fixes ``R_world = I``.
"""
from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import torch
from torch import nn

from cerberus_core.errors import ConfigError, ShapeError
from cerberus_core.fields import Checked, Range, check_kind, ranged
from cerberus_core.model.encoder import ResNet10, UpDecoder
from cerberus_core.model.heads import (
    KeypointMaps,
    RotationHead,
    ShapeHead,
    TranslationHead,
    features_under,
    unproject_expectation,
)
from cerberus_core.parts import PartSet
from cerberus_core.render.camera import Camera
from cerberus_core.render.templates import MeshTemplate, icosphere
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor


@dataclass
class ModelConfig(Checked):
    """Architecture hyper-parameters (the ``model:`` section of a training config).

    Attributes:
        num_parts: ``N``, the number of parts (9 in the paper; 1 for the NMRr baseline).
        sphere_level: icosphere subdivision level of each part's template (2: 162 vertices,
            320 faces, the paper's; 3: 642 vertices, used by the NMRr preset).
        width: channels of the first ResNet stage (64 gives the paper's 64, 128, 256, 512).
        shape_latent_dim: size of the shape latent ``S``.
        init_scale: radius of each part's initial sphere (world units).
        displacement_scale: output scale of the vertex-displacement map (a per-layer learning
            rate under Adam, see :class:`~cerberus_core.model.heads.ShapeHead`).
        vertex_bound: ``null`` (the paper's Cerberus: displacements added to the template as they
            are) or ``b > init_scale``: every local vertex coordinate is squashed into ``(-b, b)``
            as in Kato et al.'s NMR decoder (see :class:`~cerberus_core.model.heads.ShapeHead`).
            The NMRr preset uses 0.5, the half-size of the normalised object box.
        recentre: ``false`` (the paper) or ``true``: each part's vertex mean is kept at its local origin, so
            the part is centred on its translation and a part can reach a limb only by moving its keypoint
            there, not by shifting its vertices (beyond the paper; see
            :class:`~cerberus_core.model.heads.ShapeHead`).
        axis_scales: ``false`` (the paper: each part is its template sphere plus the displacement map) or ``true``:
            each part's sphere is first scaled along its three local axes by factors read from the shape latent (1 at
            the start, a quarter to four times), so a part can become a long thin ellipsoid along a limb as one
            coherent change instead of stretching a few vertices into a spike (beyond the paper, issue 38; see
            :class:`~cerberus_core.model.heads.ShapeHead`). The axes turn with the part's rotation.
        local_rotation: ``false`` (the paper: every part's quaternion is a linear map of the image's global latent) or
            ``true``: each part's quaternion also reads the decoder features under its own keypoint map (their
            expectation under it, as equation 1 takes the part's depth; the map detached, so the rotation reads
            where the part is and does not move it), through a map of its own that is zero at the start (beyond
            the paper, issue 38; see :class:`~cerberus_core.model.heads.RotationHead`). Needs a rotation head
            (``rotation: camera`` or ``world``).
        deformation_warmup: ``0`` (the paper) or ``S`` steps: for the first ``S`` training steps the parts are the
            template spheres (no displacement, and no gradient to the displacement map), then they deform freely
            (beyond the paper, issue 38): the parts can cover the body only by moving while the keypoints find their
            place (:meth:`Cerberus.deformation_gain`). A linear ramp of the displacements instead (its first form)
            did not hold them: Adam grows the weights to match, and the parts were spikes by a third of the ramp.
        anchor_spread: parts start at keypoints on a grid spanning ``[-spread, spread]`` of the
            normalised image (0: all at the centre); see
            :class:`~cerberus_core.model.heads.TranslationHead`.
        anchor_width: ``null`` (the bump each part's keypoint starts as is ``anchor_spread`` wide,
            which starts the outer parts at 0.32-0.35 of the half-image for any spread from 0.4 to 0.8)
            or the bump's width in normalised image coordinates: narrower, each part starts on its
            anchor (beyond the paper, which leaves the initialisation open).
        depth_offset: initial depth of every part (world units); ``"auto"`` in a config means the
            dataset's camera distance, resolved by the trainer before the model is built.
        rotation: what each part's rotation is. ``"camera"`` (the paper, section 3): the rotation head's quaternion
            is the part's rotation relative to the camera, so its world rotation is ``R^T Q``, and a part whose head
            still says "identity" is turned with the camera. ``"none"``: every part's world rotation is the identity
            (the NMR baseline, which deforms one sphere in the world frame; the head is not run,
            :attr:`Cerberus.trains_every_parameter`). ``"world"`` (beyond the paper, issue 38):
            the same head's quaternion is the part's world rotation, so the model starts as ``"none"`` and turns a
            part only where the images ask for it; the network then reads a part's orientation in the world from the
            image, as NMR's world-frame deformation does (the bodies of a dataset share one world frame: the
            generator's bodies stand up +Y and face +Z). Saved configs of earlier versions hold
            ``predict_rotation: true / false``, read as ``"camera"`` / ``"none"``.
        body_depth: ``false`` (the paper: each part's depth is read from the features under its keypoint) or
            ``true``: one depth shift per image, a linear map of the image's global latent (zero at the start), is
            added to every part's depth, so the whole body's distance is read from the whole image (beyond the
            paper, issue 38: one shift per image is most of what the depth oracle corrects; see
            :class:`~cerberus_core.model.heads.TranslationHead`).
        root_part: ``false`` (the paper: every part alike) or ``true``: part 0, the one whose keypoint starts at the
            image centre, is the NMRr baseline's one mesh inside Cerberus: it starts as NMRr's sphere (radius 0.3,
            its coordinates bounded by 0.5) and deforms in the world frame (identity world rotation, as ``rotation:
            none``), while the other parts keep ``init_scale``, ``vertex_bound`` and ``rotation`` (beyond the paper,
            issue 38: the single mesh keeps learning after the parts stop; see
            :class:`~cerberus_core.model.heads.ShapeHead`). Needs at least two parts.
    """

    SECTION = "model"
    RENAMED = {"predict_rotation": ("rotation", {True: "camera", False: "none"})}

    num_parts: int = ranged(9, ge=1, le=64)
    sphere_level: int = ranged(2, ge=0, le=5)
    width: int = ranged(64, ge=1)
    shape_latent_dim: int = ranged(256, ge=1)
    init_scale: float = ranged(0.12, gt=0)
    displacement_scale: float = ranged(0.05, gt=0)
    vertex_bound: float | None = ranged(None, gt=0, integer=False)
    recentre: bool = False
    axis_scales: bool = False
    local_rotation: bool = False
    deformation_warmup: int = ranged(0, ge=0)
    anchor_spread: float = ranged(0.4, ge=0, lt=1)
    anchor_width: float | None = ranged(None, gt=0, integer=False)
    depth_offset: float | str = "auto"
    rotation: Literal["camera", "world", "none"] = "camera"
    body_depth: bool = False
    root_part: bool = False

    def validate(self) -> None:
        """The checks between fields (the ranges are declared above)."""
        if self.local_rotation and self.rotation == "none":
            raise ConfigError("model.local_rotation reads features into the rotation head, which model.rotation: none "
                              "does not run; set model.rotation=camera (or world), or model.local_rotation=false",
                              key="model.local_rotation", value=self.local_rotation)
        if self.root_part and self.num_parts < 2:
            raise ConfigError("model.root_part makes part 0 the single mesh beside the other parts and needs "
                              "model.num_parts >= 2; for one mesh alone use the nmrr preset, or set "
                              "model.root_part=false", key="model.root_part", value=self.root_part)
        if self.vertex_bound is not None and not self.vertex_bound > self.init_scale:
            raise ConfigError(f"model.vertex_bound must be null or larger than model.init_scale "
                              f"({self.init_scale}), got {self.vertex_bound!r}", key="model.vertex_bound", value=self.vertex_bound)
        if isinstance(self.depth_offset, str):
            if self.depth_offset != "auto":
                raise ConfigError(f"model.depth_offset must be a number or 'auto', got {self.depth_offset!r}", key="model.depth_offset", value=self.depth_offset)
        elif not Range(gt=0).admits(self.depth_offset):
            raise ConfigError(f"model.depth_offset must be positive or 'auto', got {self.depth_offset!r}", key="model.depth_offset", value=self.depth_offset)

@dataclass
class Predictions:
    """What the network predicts from ``B`` images, before the camera is used.

    Attributes:
        object_latent: ``(B, 8 * width)`` global average of the lowest-resolution features.
        shape_latent: ``(B, S)`` each image's own shape latent.
        render_latent: ``(B, S)`` the shape latent the meshes were built from (``shape_latent``
            unless a pose-consistency mixer replaced it, equation 3).
        local_vertices: ``(B, N, V, 3)`` deformed part templates in the parts' local frames.
        quaternions: ``(B, N, 4)`` the rotation head's unit quaternions ``(w, x, y, z)``, relative to the camera
            (``model.rotation: camera``) or to the world (``world``); unused with ``none``.
        rotations: ``(B, N, 3, 3)`` the rotation matrices of ``quaternions``.
        maps: per-part probability and depth maps and their expectations.
    """

    object_latent: Tensor
    shape_latent: Tensor
    render_latent: Tensor
    local_vertices: Tensor
    quaternions: Tensor
    rotations: Tensor
    maps: KeypointMaps


def check_image_dtype(images: Tensor, what: str, dtype: torch.dtype) -> None:
    """:class:`ShapeError` unless ``images`` are ``(B, 3, H, W)`` of ``dtype`` (the weights' dtype: a uint8 image
    names its conversion from 0-255; a numpy array names ``torch.from_numpy``), before any layer sees them."""
    check_kind("images", images, torch.Tensor, "a torch.Tensor (B, 3, H, W); from numpy, torch.from_numpy(images)")
    check_shapes(what, images=(images, "B 3 H W"))
    name = str(dtype).removeprefix("torch.")
    convert = "images.float()" if dtype == torch.float32 else f"images.to(torch.{name})"
    if images.dtype == torch.uint8:
        raise ShapeError(f"{what}: the images are uint8 (0-255); pass {convert} / 255 ({name} in [0, 1])")
    if images.dtype != dtype:
        raise ShapeError(f"{what}: the images are {images.dtype}; pass {convert} ({name} in [0, 1])")


def check_images(images: Tensor, what: str) -> None:
    """The network's input contract: ``(B, 3, H, W)`` float32 in ``[0, 1]``, every value a number
    (:class:`ShapeError` naming the conversion otherwise; a uint8 or 0-255 image would silently give a wrong
    reconstruction, a NaN one a NaN model)."""
    check_image_dtype(images, what, torch.float32)
    if images.numel() and not bool(torch.isfinite(images).all()):
        bad = int((~torch.isfinite(images)).sum())
        raise ShapeError(f"{what}: {bad} of {images.numel()} image values are NaN or infinite; images are float32 in "
                         "[0, 1] (check how they were loaded or normalised)")
    if images.numel() and float(images.detach().amax()) > 1.0 + 1e-3:
        raise ShapeError(f"{what}: image values reach {float(images.detach().amax()):.4g}, above 1; images are "
                         "float32 in [0, 1] (divide 0-255 images by 255)")


class Cerberus(nn.Module):
    """The multi-headed derenderer.

    Args:
        config: a :class:`ModelConfig` with a numeric ``depth_offset``.
    """

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        config.check()
        if isinstance(config.depth_offset, str):
            raise ConfigError.about("model.depth_offset", config.depth_offset, "Cerberus: still 'auto'; set it to the "
                                    "camera distance (the trainer does this from the dataset's scene)",
                                    "`model.depth_offset=VALUE`")
        self.config = config
        self.template: MeshTemplate = icosphere(config.sphere_level)
        self.register_buffer("faces", self.template.faces.clone(), persistent=False)
        self.register_buffer("dihedral", self.template.dihedral.clone(), persistent=False)
        self.encoder = ResNet10(3, config.width)
        self.decoder = UpDecoder(self.encoder.channels)
        latent = self.encoder.out_channels
        self.shape = ShapeHead(latent, config.shape_latent_dim, config.num_parts, self.template.vertices,
                               config.init_scale, config.displacement_scale, config.vertex_bound,
                               config.recentre, config.axis_scales, config.root_part)
        self.rotation = RotationHead(latent, config.num_parts,
                                     self.decoder.out_channels if config.local_rotation else None)
        self.translation = TranslationHead(self.decoder.out_channels, config.num_parts, float(config.depth_offset),
                                           config.anchor_spread, config.anchor_width,
                                           latent if config.body_depth else None)
        self.cnn_autocast: torch.dtype | None = None
        """Run the convolutional trunk (encoder and decoder) under ``torch.autocast`` to this dtype
        (``None``: off). The heads, and so all geometry, stay in the input dtype; set by the
        training switch ``speed.autocast`` (:mod:`cerberus_core.train.speed`), not saved."""

    @property
    def num_parts(self) -> int:
        return self.config.num_parts

    @property
    def trains_every_parameter(self) -> bool:
        """Whether every parameter takes part in :meth:`forward`. ``False`` with ``model.rotation: none``: the
        rotation head is built, so that the models of every setting hold the same tensors and load alike, but it
        is not run (its parameters keep their initial values and get no gradient; data-parallel training must
        then look for parameters without one, ``find_unused_parameters``)."""
        return self.config.rotation != "none"

    def deformation_gain(self, step: int | None) -> float:
        """The share of the vertex displacements used at training step ``step`` (``model.deformation_warmup: S``): 0
        before step ``S``, 1 from it on; 1 without a hold and outside training (``step=None``).

        Example:
            >>> model = Cerberus(ModelConfig(num_parts=2, width=4, shape_latent_dim=8, depth_offset=2.0,
            ...                              deformation_warmup=1000))
            >>> model.deformation_gain(0), model.deformation_gain(999), model.deformation_gain(1000), model.deformation_gain(None)
            (0.0, 0.0, 1.0, 1.0)
        """
        return 0.0 if step is not None and step < self.config.deformation_warmup else 1.0

    def forward(self, images: Tensor, mix: Callable[[Tensor], Tensor] | None = None, *,
                step: int | None = None) -> Predictions:
        """Predict parts from images.

        Args:
            images: ``(B, 3, H, W)`` in [0, 1], H and W at least 32.
            mix: optional map ``(B, S) → (B, S)`` applied to the shape latents before they are
                decoded into vertices (pose consistency, equation 3).
            step: the training step, for ``model.deformation_warmup`` (``None``: a trained model's full
                deformation).
        """
        check_image_dtype(images, "Cerberus", next(self.parameters()).dtype)
        c4, features = self._cnn(images)
        object_latent = c4.mean(dim=(-2, -1))
        shape_latent = self.shape.latent(object_latent)
        render_latent = shape_latent if mix is None else mix(shape_latent)
        local = self.shape.deform(render_latent, self.deformation_gain(step))
        maps = self.translation(features, tuple(images.shape[-2:]), object_latent)
        if not self.trains_every_parameter:
            quats, rot_cam = self.rotation.identity(object_latent)
        else:  # with model.local_rotation each part reads the features under its map (detached: read, not moved)
            read = features_under(maps.prob.detach(), features) if self.config.local_rotation else None
            quats, rot_cam = self.rotation(object_latent, read)
        return Predictions(object_latent, shape_latent, render_latent, local, quats, rot_cam, maps)

    def _cnn(self, images: Tensor) -> tuple[Tensor, Tensor]:
        """The convolutional trunk: the lowest-resolution features ``c4`` and the decoder's output,
        both dense and in the input dtype (no-ops unless :attr:`cnn_autocast` or a channels-last
        trunk changed them)."""
        amp = self.cnn_autocast
        with torch.autocast(images.device.type, dtype=amp) if amp is not None else contextlib.nullcontext():
            pyramid = self.encoder(images)
            features = self.decoder(pyramid)
        return (pyramid.c4.to(images.dtype).contiguous(), features.to(images.dtype).contiguous())

    def world_pose(self, pred: Predictions, camera: Camera) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        """Part rotations and translations in both frames.

        Returns:
            ``(rotations, translations, rotations_cam, translations_cam)``: world ``(B, N, 3, 3)``,
            ``(B, N, 3)``, then the camera-frame ones.
        """
        t_cam = unproject_expectation(pred.maps, camera, to_world=False)
        t_world = camera.camera_to_world(t_cam)
        if self.config.rotation == "camera":
            r_cam = pred.rotations
            r_world = camera.rotation_to_world(r_cam)
        else:
            r_world = pred.rotations if self.config.rotation == "world" else \
                torch.eye(3, dtype=t_cam.dtype, device=t_cam.device).expand_as(pred.rotations)
            r_cam = camera.rotation.unsqueeze(1) @ r_world
        if self.config.root_part:  # part 0 deforms in the world frame, as NMRr's one mesh (rotation: none)
            eye = torch.eye(3, dtype=t_cam.dtype, device=t_cam.device).expand(r_world.shape[0], 1, 3, 3)
            r_world = torch.cat([eye, r_world[:, 1:]], dim=1)
            r_cam = torch.cat([camera.rotation.unsqueeze(1).to(t_cam.dtype), r_cam[:, 1:]], dim=1)
        return r_world, t_world, r_cam, t_cam

    def pose(self, pred: Predictions, camera: Camera, frame: str = "world") -> PartSet:
        """Place the predicted parts with the cameras that took the images.

        Args:
            frame: ``"world"`` (the default: rotations and translations in the world frame) or
                ``"camera"`` (relative to each image's camera).
        """
        r_world, t_world, r_cam, t_cam = self.world_pose(pred, camera)
        if frame == "world":
            return PartSet(pred.local_vertices, self.faces, r_world, t_world)
        if frame == "camera":
            return PartSet(pred.local_vertices, self.faces, r_cam, t_cam)
        raise ConfigError.about("frame", frame, "Cerberus.pose: must be 'world' or 'camera'")

    def reconstruct(self, images: Tensor, camera: Camera) -> PartSet:
        """Images and their known cameras → posed parts in the world frame (differentiable; no mode
        change: call ``model.eval()`` first for inference)."""
        check_images(images, "reconstruct")
        if camera.batch_size != images.shape[0]:
            raise ShapeError(f"reconstruct: {images.shape[0]} images but {camera.batch_size} cameras; pass one camera "
                             "per image")
        return self.pose(self(images), camera)
