"""One training objective evaluation: predict, pose, render and combine every loss (sections 3–5).

For a batch of ``B`` quadruplets the model sees ``4 B`` images. With viewpoint consistency on, the
renderer draws ``8 B`` scenes in one call: each image's rotated parts with its own translation from
its own viewpoint, and with its viewpoint partner's translation from the partner's viewpoint
(equation 4). The total loss is

``lambda_r L_r' + lambda_t L_t' + lambda_b L_b + lambda_s L_s``

averaged over the batch, plus the terms beyond the paper (weight 0 in its settings). Each term is
declared once, as a weight field of :class:`LossConfig` (the ``losses:`` config section: its name,
its weight in the paper's settings, how its value is computed from the objective's inputs, whether
it is always logged, its symbol and where it comes from); :data:`TERM_TABLE`, the columns of
``metrics.csv`` and the docs' table (:func:`terms_table`) are read from those fields. The functions behind the
terms are :mod:`cerberus_core.losses`. Beyond the paper too: ``antialias`` renders with the analytic
anti-aliasing op, which gives the image and the coverage visibility gradients, and ``losses.cross_view:
own`` renders the cross view with each image's own 3D model.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any, Literal

import torch
from torch import nn

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import ConfigError, InputTypeError
from cerberus_core.fields import RANGE, Checked, Range, ranged
from cerberus_core.losses import (
    VIEW_PARTNER,
    NearestSearch,
    background_loss,
    background_mask,
    body_translation_loss,
    hidden_part_pull,
    keep_own_elements,
    mix_shape_latents,
    part_overlap,
    part_separation,
    part_tips,
    pose_consensus,
    reconstruction_loss,
    relocation_pull,
    reprojection_loss,
    rotation_loss,
    silhouette_chamfer,
    silhouette_coverage,
    silhouette_loss,
    smoothness_loss,
    translation_loss,
    triangulated_body_depth_loss,
    viewpoint_reconstruction,
    viewpoint_scenes,
)
from cerberus_core.model.cerberus import Cerberus, Predictions
from cerberus_core.parts import PartSet
from cerberus_core.render.api import part_pixel_counts, render_parts
from cerberus_core.render.camera import Camera, triangulate
from cerberus_core.render.interface import Renderer, RenderOutput
from cerberus_core.train.data import QuadrupletBatch

Tensor = torch.Tensor

__all__ = ["TERMS", "TERM_TABLE", "LossConfig", "ObjectiveOutput", "Term", "quadruplet_objective", "terms_table"]


@dataclass
class ObjectiveOutput:
    """Attributes:
        total: scalar loss to minimise (NaN if the predicted geometry was not finite; then nothing
            was rendered).
        terms: detached scalars of every term of :data:`TERMS` and ``total``.
        finite: whether ``total`` is finite.
        renders: ``(B, 4, 3, H, W)`` each image's own-viewpoint rendering (detached), or ``None``.
        parts: ``(B, 4, N, V, 3)`` the world-space parts rendered for each own viewpoint (detached).
    """

    total: Tensor
    terms: dict[str, Tensor]
    finite: bool
    renders: Tensor | None = None
    parts: Tensor | None = None


def unwrap(model: nn.Module) -> Cerberus:
    """The :class:`Cerberus` inside a DistributedDataParallel wrapper (or the model itself)."""
    inner = getattr(model, "module", model)
    if not isinstance(inner, Cerberus):
        raise InputTypeError(f"expected a Cerberus model, got {type(inner).__name__}; pass a `Cerberus` (or one "
                             "wrapped in DistributedDataParallel)")
    return inner


def quadruplet_mixer(generator: torch.Generator | None, mixing: float = 1.0) -> Callable[[Tensor], Tensor]:
    """Pose consistency for flattened quadruplets: ``(4 B, S)`` own latents → ``(4 B, S)`` where the
    four images of each quadruplet share one mixed latent (equation 3).

    ``mixing`` below 1 (``losses.pose_mixing``, beyond the paper) makes the consistency partial: each element of
    each image's latent is the quadruplet's mixed element with probability ``mixing`` and the image's own
    otherwise (:func:`cerberus_core.losses.keep_own_elements`); 1 is equation 3 and draws nothing more.
    """
    def mix(latents: Tensor) -> Tensor:
        quads = latents.view(-1, 4, latents.shape[-1])
        mixed, _ = mix_shape_latents(quads, generator)
        shared = mixed.unsqueeze(1).expand_as(quads)
        if mixing < 1:
            shared = keep_own_elements(shared, quads, mixing, generator)
        return shared.reshape_as(latents)
    return mix


def partner_cameras(camera: Camera, num_quadruplets: int) -> Camera:
    """For flattened quadruplet cameras ``4 b + k``, the camera of ``4 b + VIEW_PARTNER[k]``."""
    idx = (torch.arange(num_quadruplets).view(-1, 1) * 4 + torch.tensor(VIEW_PARTNER).view(1, 4)).reshape(-1)
    return camera.index(idx.to(camera.device))


def smoothness_term(local_vertices: Tensor, dihedral: Tensor, num_quadruplets: int, once: bool) -> Tensor:
    """``(4 B,)`` smoothness loss per image; ``once``: computed for the first image of each quadruplet
    and repeated (valid when the four share their meshes: pose consistency), a quarter of the work.
    Its mean equals the full computation's bit for bit when the meshes are equal."""
    if not once:
        return smoothness_loss(local_vertices, dihedral)
    first = local_vertices.view(num_quadruplets, 4, *local_vertices.shape[1:])[:, 0]
    return smoothness_loss(first, dihedral).unsqueeze(1).expand(num_quadruplets, 4).reshape(-1)


@dataclass
class QuadrupletRender:
    """The renderings of equation 4 for ``B`` quadruplets.

    Attributes:
        own: each image's parts from its own viewpoint: ``image`` ``(B, 4, 3, H, W)``, ``alpha``
            ``(B, 4, 1, H, W)``, ``part_id`` ``(B, 4, H, W)``.
        cross: each image's rotated parts with the partner's translation from the partner's
            viewpoint (``None`` without viewpoint consistency); ``cross[:, x]`` is compared with
            image ``VIEW_PARTNER[x]``.
        parts_own: ``(B, 4, N, V, 3)`` the world-space parts of ``own``.
        parts_cross: ``(B, 4, N, V, 3)`` the world-space parts of ``cross`` (``None`` without it).
    """

    own: RenderOutput
    cross: RenderOutput | None
    parts_own: Tensor
    parts_cross: Tensor | None = None


def render_quadruplets(renderer: Renderer, parts: PartSet, batch: QuadrupletBatch, scene: SceneSetup,
                       background: tuple[float, float, float], *, viewpoint_consistency: bool,
                       antialias: bool, cross_view: str = "partner") -> QuadrupletRender:
    """Render ``parts`` (``4 B`` images' world-space parts) as equation 4 asks, in one renderer call
    (``cross_view``: :func:`cerberus_core.losses.viewpoint_scenes`)."""
    bsz = batch.num_quadruplets

    def quad(t: Tensor) -> Tensor:  # (4B, ...) -> (B, 4, ...)
        return t.reshape(bsz, 4, *t.shape[1:])

    own, cross = viewpoint_scenes(quad(parts.local_vertices), quad(parts.rotations), quad(parts.translations),
                                  cross_view)
    style = dict(albedo=scene.albedo, background=background, antialias=antialias)
    if viewpoint_consistency:
        cameras = Camera.cat([batch.camera, partner_cameras(batch.camera, bsz)])
        verts = torch.cat([own.flatten(0, 1), cross.flatten(0, 1)])
    else:
        cameras, verts = batch.camera, own.flatten(0, 1)
    out = render_parts(renderer, verts, parts.faces, cameras, scene.light(cameras), **style)
    views = {f.name: getattr(out, f.name).split(4 * bsz) for f in fields(out)}  # own, then cross
    halves = [RenderOutput(**{name: quad(t[k]) for name, t in views.items()}) for k in range(len(views["image"]))]
    if not viewpoint_consistency:
        return QuadrupletRender(halves[0], None, own)
    return QuadrupletRender(halves[0], halves[1], own, cross)


@dataclass
class ObjectiveInputs:
    """Everything the terms of the objective read, for ``B`` quadruplets (``4 B`` images).

    Attributes:
        batch: the quadruplets and their cameras.
        pred: the network's predictions for the ``4 B`` images.
        parts: their world-space parts (:class:`PartSet`, ``4 B`` images).
        mask: ``(4 B, 1, H, W)`` the inputs' background mask ``b``.
        targets: ``(B, 4, 3, H, W)`` the images compared with the renderings (background black with
            ``losses.render_background: black``).
        render: the renderings (:class:`QuadrupletRender`).
        dihedral: the template's dihedral quadruples; ``smoothness_once``: see :func:`smoothness_term`.
        search: the pulls' nearest-neighbour search (the renderer backend's kernel,
            :meth:`Renderer.nearest_indices`).
        cross_pulls, consensus_tips: the switches of :class:`LossConfig`; cross_view: the cross view of this step
            (:meth:`LossConfig.cross_view_at`), which the render used.
    """

    batch: QuadrupletBatch
    pred: Predictions
    parts: PartSet
    mask: Tensor
    targets: Tensor
    render: QuadrupletRender
    dihedral: Tensor
    smoothness_once: bool
    search: NearestSearch
    cross_pulls: bool = False
    consensus_tips: bool = False
    cross_view: Literal["partner", "own"] = "partner"
    _uv: Tensor | None = field(default=None, repr=False)
    _uv_cross: Tensor | None = field(default=None, repr=False)
    _held: tuple[Tensor, Tensor] | None = field(default=None, repr=False)

    @property
    def foreground(self) -> Tensor:
        """``(B, 4, 1, H, W)`` 1 on the inputs' body pixels."""
        return (1 - self.mask).view(self.batch.num_quadruplets, 4, *self.mask.shape[1:])

    @property
    def uv(self) -> Tensor:
        """``(4 B, N V, 2)`` the own-viewpoint parts' vertices projected into their images, in pixels."""
        if self._uv is None:
            self._uv, _ = self.batch.camera.project(self.render.parts_own.flatten(0, 1).flatten(1, 2))
        return self._uv

    @property
    def uv_cross(self) -> Tensor:
        """``(4 B, N V, 2)`` the cross-view parts' vertices projected into the partner cameras, in
        pixels (row ``4 b + x`` is seen by image ``4 b + VIEW_PARTNER[x]``'s camera)."""
        if self._uv_cross is None:
            cams = partner_cameras(self.batch.camera, self.batch.num_quadruplets)
            self._uv_cross, _ = cams.project(self.render.parts_cross.flatten(0, 1).flatten(1, 2))
        return self._uv_cross

    @property
    def held_scenes(self) -> tuple[Tensor, Tensor]:
        """``(B, 4, N, V, 3)`` twice: the own and cross views' world-space parts posed as the render's
        (:func:`cerberus_core.losses.viewpoint_scenes` with ``cross_view``) with each local shape detached
        (``R sg(L) + T``), so a gradient through them reaches the rotations and translations only."""
        if self._held is None:
            shapes = _quad(self.parts.local_vertices.detach(), self)
            self._held = viewpoint_scenes(shapes, _quad(self.parts.rotations, self), _quad(self.parts.translations, self),
                                          self.cross_view)
        return self._held

    @property
    def pulls_cross(self) -> bool:
        """Whether the chamfer, coverage and hidden-part pulls also act on the cross view."""
        return self.cross_pulls and self.render.cross is not None


def _partner(t: Tensor) -> Tensor:
    return t[:, list(VIEW_PARTNER)]


def _recon(x: ObjectiveInputs) -> Tensor:
    own = reconstruction_loss(x.render.own.image, x.targets)
    cross = None if x.render.cross is None else reconstruction_loss(x.render.cross.image, _partner(x.targets))
    return viewpoint_reconstruction(own, cross)


def _silhouette(x: ObjectiveInputs) -> Tensor:
    own = silhouette_loss(x.render.own.alpha, x.foreground)
    cross = None if x.render.cross is None else silhouette_loss(x.render.cross.alpha, _partner(x.foreground))
    return viewpoint_reconstruction(own, cross)


def _quad(t: Tensor, x: ObjectiveInputs) -> Tensor:  # (4B, ...) -> (B, 4, ...)
    return t.view(x.batch.num_quadruplets, 4, *t.shape[1:])


def _vertex_uv(x: ObjectiveInputs, cross: bool, held: bool) -> Tensor:
    """``(4 B, N V, 2)`` the parts' vertices projected in the input view (:attr:`ObjectiveInputs.uv`) or the cross
    view (``uv_cross``); with ``held``, of the same parts with their local shapes detached (``R sg(L) + T``), so a
    gradient reaches their rotations and translations only."""
    if not held:
        return x.uv_cross if cross else x.uv
    cams = partner_cameras(x.batch.camera, x.batch.num_quadruplets) if cross else x.batch.camera
    return cams.project(x.held_scenes[int(cross)].flatten(0, 1).flatten(1, 2))[0]


def _vertex_pull(pull: Callable[..., Tensor], held: bool = False) -> Callable[[ObjectiveInputs], Tensor]:
    """A pull of the projected part vertices onto the input's foreground (``pull(points, foreground,
    search=...)`` ``-> (4 B,)``, with the renderer's nearest-neighbour search), in the input view and,
    with ``cross_pulls``, the cross view, averaged like eq. 4; with ``held`` the parts' shapes are detached
    (:func:`_vertex_uv`), so the pull turns and moves whole parts."""
    def value(x: ObjectiveInputs) -> Tensor:
        own = _quad(pull(_vertex_uv(x, False, held), x.foreground.flatten(0, 1), search=x.search), x)
        cross = (_quad(pull(_vertex_uv(x, True, held), _partner(x.foreground).flatten(0, 1), search=x.search), x)
                 if x.pulls_cross else None)
        return viewpoint_reconstruction(own, cross)
    return value


_chamfer = _vertex_pull(silhouette_chamfer)
_coverage = _vertex_pull(silhouette_coverage)
_rigid_coverage = _vertex_pull(silhouette_coverage, held=True)


def _consensus_uv(x: ObjectiveInputs, tips: bool = False) -> Tensor:
    """(4B, N, 2) the pose's agreed translations in each image; with ``tips`` (4B, 2N, 2): then the agreed tips."""
    points = _quad(x.parts.translations, x)  # (B, 4, N, 3)
    if tips:
        points = torch.cat([points, part_tips(_quad(x.parts.local_vertices, x), _quad(x.parts.rotations, x), points)], 2)
    return x.batch.camera.project(pose_consensus(points).flatten(0, 1))[0]


def _consensus_coverage(x: ObjectiveInputs) -> Tensor:  # (4B,): the pose's agreed points over each image
    return silhouette_coverage(_consensus_uv(x, x.consensus_tips), x.foreground.flatten(0, 1), search=x.search)


def _relocation(x: ObjectiveInputs) -> Tensor:  # (4B,): spare parts' agreed translations to the body ends
    return relocation_pull(_quad(_consensus_uv(x), x), x.render.own.part_id, x.foreground,
                           _quad(x.pred.maps.uv, x)).flatten()


def _keypoint_coverage(x: ObjectiveInputs) -> Tensor:  # (4B,): each image's keypoints over its own foreground
    return silhouette_coverage(x.pred.maps.uv, x.foreground.flatten(0, 1), search=x.search)


def _hidden_in(render: RenderOutput, uv: Tensor, foreground: Tensor, x: ObjectiveInputs) -> Tensor:
    part_id = render.part_id.flatten(0, 1)  # (4B, H, W), -1 where no part
    n, v = x.parts.num_parts, x.parts.num_vertices
    uncovered = foreground.flatten(0, 1)[:, 0] * (part_id < 0)
    return _quad(hidden_part_pull(uv.view(-1, n, v, 2), part_pixel_counts(part_id, n) > 0, uncovered,
                                  search=x.search), x)


def _hidden(x: ObjectiveInputs) -> Tensor:
    own = _hidden_in(x.render.own, x.uv, x.foreground, x)
    cross = _hidden_in(x.render.cross, x.uv_cross, _partner(x.foreground), x) if x.pulls_cross else None
    return viewpoint_reconstruction(own, cross)


def _reprojection(x: ObjectiveInputs) -> Tensor:
    bsz, n = x.batch.num_quadruplets, x.parts.num_parts
    projected, _ = partner_cameras(x.batch.camera, bsz).project(x.parts.translations)  # (4B, N, 2)
    keypoints = _partner(x.pred.maps.uv.view(bsz, 4, n, 2))
    return reprojection_loss(projected.view(bsz, 4, n, 2), keypoints, x.batch.camera.height)


def _triangulated_depth(x: ObjectiveInputs) -> Tensor:  # (B,): each view's body depth against the pose's rays
    bsz, n = x.batch.num_quadruplets, x.parts.num_parts
    camera = x.batch.camera
    rays = camera.rays(x.pred.maps.uv.detach())  # (4B, N, 3): the target moves no keypoint
    c, d = camera.center.view(bsz, 4, 3), rays.view(bsz, 4, n, 3)
    partner = list(VIEW_PARTNER)
    points = triangulate(torch.stack([c, c[:, partner]], 2), torch.stack([d, d[:, partner]], 2))  # (B, 4, N, 3)
    _, target = camera.project(points.view(4 * bsz, n, 3))
    weight = (1 - (d * d[:, partner]).sum(-1).square()).mean(-1)  # (B, 4): sin^2 of the rays' angle
    return triangulated_body_depth_loss(x.pred.maps.depth.view(bsz, 4, n), target.view(bsz, 4, n), weight)


BEYOND = "beyond the paper"
TERM = "cerberus.term"
"""The ``dataclasses.field`` metadata key of a weight field of :class:`LossConfig` that holds its :class:`Term`."""


@dataclass(frozen=True)
class Term:
    """One term of the training objective, declared once: as a weight field of :class:`LossConfig`
    (:func:`term`); :data:`TERM_TABLE` lists them.

    Attributes:
        name: its name everywhere: the weight ``losses.<name>`` (the field's name), the column of
            ``metrics.csv``, the key of :attr:`ObjectiveOutput.terms`.
        weight: its weight in the paper's settings, the field's default (0: beyond the paper, off there).
        value: how the objective computes it from its inputs: ``ObjectiveInputs -> (B,)`` per
            quadruplet or ``(4 B,)`` per image, averaged over the batch.
        always_logged: computed and logged even at weight 0 (cheap); the others only when weighted.
        symbol: its symbol in the total ``sum_k lambda_k L_k``.
        source: where it comes from: the paper's equations, or ``beyond the paper``.
        summary: what it measures, in one line (docs, :func:`terms_table`).
        function: the function of :mod:`cerberus_core.losses` that defines it.
        allocation: a pull that decides where the parts go (issue 38): with ``losses.allocation_steps: S``
            its weight fades linearly to 0 over the first ``S`` steps (:meth:`LossConfig.weights_at`).
    """

    name: str
    weight: float
    value: Callable[[ObjectiveInputs], Tensor]
    always_logged: bool
    symbol: str
    source: str
    summary: str
    function: Callable[..., Tensor]
    allocation: bool = False

    @property
    def paper(self) -> bool:
        """Whether the paper has it."""
        return self.source != BEYOND


def term(weight: float, value: Callable[[ObjectiveInputs], Tensor], symbol: str, source: str, summary: str,
         function: Callable[..., Tensor], *, always_logged: bool = False, allocation: bool = False) -> Any:
    """A weight field of :class:`LossConfig` that declares its term: the paper's ``weight`` as the default (checked
    >= 0), and the rest of its :class:`Term` (its ``name`` is the field's)."""
    spec = dict(value=value, always_logged=always_logged, symbol=symbol, source=source, summary=summary,
                function=function, allocation=allocation)
    return field(default=weight, metadata={RANGE: Range(ge=0), TERM: spec})


@dataclass
class LossConfig(Checked):
    """Loss weights and consistency switches: the ``losses:`` section of a training config.

    **The terms.** Each weight field is one term of the objective, declared once with :func:`term`: its weight in
    the paper's settings (the default; 0 switches the term off, though the always-logged ones are still computed,
    and a weight must be >= 0), how the objective computes it, its symbol, where it comes from and the function
    of :mod:`cerberus_core.losses` behind it. To add a term, write its function in :mod:`cerberus_core.losses`
    and one field here, with weight 0 when the paper does not have it (docs/training.md, "Adding a loss term");
    :data:`TERM_TABLE`, the ``metrics.csv`` columns and the docs' table follow. The paper's total is
    ``lambda_r L_r' + lambda_t L_t' + lambda_b L_b + lambda_s L_s``.

    **The switches.**

    Attributes:
        pose_consistency: render with the mixed shape latent of equation 3 (off: each image uses its own shape
            latent, 'Free Cerberus').
        pose_mixing: with pose consistency, the probability that an element of an image's shape latent is the
            quadruplet's mixed one (else the image keeps its own; :func:`quadruplet_mixer`): 1 is equation 3, and
            lower values trade Free Cerberus's fit of each image against parts that hold across poses (beyond
            the paper, issue 38).
        viewpoint_consistency: also render each image's rotated mesh from the other viewpoint (equation 4); off:
            only the image's own viewpoint.
        cross_view: which translations that second rendering uses (:func:`cerberus_core.losses.viewpoint_scenes`):
            ``partner`` (the paper's equation 4: the partner viewpoint's translations, so a part's own depth never
            meets the partner's image) or ``own`` (the image's whole 3D model seen from the partner camera: a part
            at the wrong depth lands in the wrong place of the partner's image); beyond the paper.
        cross_view_warmup: with ``cross_view: own``, the first this many steps still use ``partner``, so that early
            training, whose depths are still arbitrary, cannot lose the body off the partner's screen
            (:meth:`cross_view_at`).
        cross_pulls: apply the chamfer, coverage, rigid coverage and hidden-part pulls to the cross view as well, against the
            partner's foreground, averaged with the input view's like equation 4; off: the input view only.
        consensus_tips: ``consensus_coverage``'s k-means also moves each part's tip (:func:`part_tips
            <cerberus_core.losses.part_tips>`, the vertex that reaches farthest, as the pose's two views agree on
            it): ``2 N`` points share the foreground, so a limb beyond a part's keypoint pulls the part's far end and
            swings the part along it; off: the keypoints only (beyond the paper, issue 38).
        render_background: the background colour of the reconstruction loss: ``black`` sets the input's background
            pixels (mask ``b``) to black in the target and composites the renderings over black (the barycentric
            renderer has no silhouette gradient, so a part over a white background would be pushed to face the
            light, which flattens and inflates it; towards black it is not); ``dataset`` keeps the dataset's colour.
        allocation_steps: the allocation pulls (:attr:`Term.allocation`: ``rigid_coverage``, ``keypoint_coverage``,
            ``consensus_coverage``, ``separation``, ``relocation``) fade linearly from their weight at step 0 to nothing
            at this step, so they place the parts early and leave the rest of training to the image terms
            (:meth:`weights_at`);
            0: full weight for the whole run (beyond the paper, issue 38).
        background_tolerance: a pixel is background (``b = 1``) when every channel is within this of the dataset's
            background colour (:func:`cerberus_core.losses.background_mask`).
    """

    SECTION = "losses"

    # the paper's terms (eqs. 2-7, section 5)
    recon: float = term(1.0, _recon, "lambda_r L_r'", "eqs. 2, 4, 7",
                        "squared RGB error of each image's rendering, own and partner viewpoint", reconstruction_loss,
                        always_logged=True)
    translation: float = term(1.0, lambda x: translation_loss(_quad(x.parts.translations, x)), "lambda_t L_t'",
                              "eqs. 5, 6", "disagreement of the translations predicted from the two viewpoints",
                              translation_loss, always_logged=True)
    background: float = term(1.0, lambda x: background_loss(x.pred.maps.prob, x.mask), "lambda_b L_b", "section 5",
                             "keypoint probability mass on the input's background", background_loss, always_logged=True)
    smoothness: float = term(0.0001, lambda x: smoothness_term(x.pred.local_vertices, x.dihedral,
                                                               x.batch.num_quadruplets, x.smoothness_once),
                             "lambda_s L_s", "section 5 (Kato et al.)", "sum over mesh edges of (cos theta + 1)^2",
                             smoothness_loss, always_logged=True)
    # beyond the paper: weight 0 in its settings
    silhouette: float = term(0.0, _silhouette, "lambda_sil L_sil", BEYOND, "squared error of the rendered coverage "
                             "against the input's foreground (needs render.antialias)", silhouette_loss,
                             always_logged=True)
    chamfer: float = term(0.0, _chamfer, "lambda_c L_c", BEYOND, "2-D chamfer distance between the projected part "
                          "vertices and the foreground pixels", silhouette_chamfer)
    hidden: float = term(0.0, _hidden, "lambda_h L_h", BEYOND, "pull of the parts an image does not show toward the "
                         "foreground no part covers", hidden_part_pull)
    reprojection: float = term(0.0, _reprojection, "lambda_p L_p", BEYOND, "each part's translation projected into "
                               "the partner camera against the partner's keypoint", reprojection_loss)
    coverage: float = term(0.0, _coverage, "lambda_cov L_cov", BEYOND, "every foreground pixel's distance to the "
                           "nearest projected part vertex, thin structures weighted up", silhouette_coverage)
    rigid_coverage: float = term(0.0, _rigid_coverage, "lambda_rc L_rc", BEYOND, "the coverage pull on each part's "
                                 "vertices with its shape held: a missed limb turns and moves the nearest part (R, T) "
                                 "instead of stretching it", silhouette_coverage, allocation=True)
    keypoint_coverage: float = term(0.0, _keypoint_coverage, "lambda_kc L_kc", BEYOND, "every foreground pixel's "
                                    "distance to the nearest part keypoint, thin structures weighted up (k-means)",
                                    silhouette_coverage, allocation=True)
    consensus_coverage: float = term(0.0, _consensus_coverage, "lambda_kv L_kv", BEYOND, "keypoint k-means over both "
                                     "views of a pose: each part's translation averaged over the pose's two viewpoints, "
                                     "projected into each image, against its foreground", pose_consensus, allocation=True)
    separation: float = term(0.0, lambda x: part_separation(x.parts.translations), "lambda_sep L_sep", BEYOND,
                             "KeypointNet's separation in 3D: parts whose translations lie closer than 0.1 push apart",
                             part_separation, allocation=True)
    relocation: float = term(0.0, _relocation, "lambda_rel L_rel", BEYOND, "spare parts (alone at most 2 % of the "
                             "pose's foreground) pulled, through the pose's agreed translation, to the uncovered "
                             "foreground farthest from the other keypoints", relocation_pull, allocation=True)
    overlap: float = term(0.0, lambda x: part_overlap(x.render.parts_own.flatten(0, 1)), "lambda_o L_o", BEYOND,
                          "share of each part's volume inside another part (each part the Gaussian of its vertices)",
                          part_overlap)
    body_translation: float = term(0.0, lambda x: body_translation_loss(_quad(x.parts.translations, x)),
                                   "lambda_bt L_bt", BEYOND, "disagreement of the whole body's translation (the mean "
                                   "of its parts') between the two viewpoints: eqs. 5, 6 blind to which part is which",
                                   body_translation_loss)
    triangulated_depth: float = term(0.0, _triangulated_depth, "lambda_td L_td", BEYOND, "each image's whole-body "
                                     "depth (mean over its parts) against the depth its and its partner's keypoint "
                                     "rays meet at (detached)", triangulated_body_depth_loss)
    rotation: float = term(0.0, lambda x: rotation_loss(_quad(x.parts.rotations, x)), "lambda_R L_R", BEYOND,
                           "disagreement of the world rotations predicted from the two viewpoints (eq. 6 for "
                           "rotations)", rotation_loss)

    # the switches
    pose_consistency: bool = True
    pose_mixing: float = ranged(1.0, gt=0, le=1)
    viewpoint_consistency: bool = True
    cross_view: Literal["partner", "own"] = "partner"
    cross_view_warmup: int = ranged(0, ge=0)
    cross_pulls: bool = False
    consensus_tips: bool = False
    allocation_steps: int = ranged(0, ge=0)
    render_background: Literal["black", "dataset"] = "black"
    background_tolerance: float = ranged(0.02, ge=0, lt=1)

    def validate(self) -> None:
        """A partial mixing needs the mixing it makes partial; the tips need the pull they join."""
        if self.consensus_tips and self.consensus_coverage <= 0:
            raise ConfigError.about("losses.consensus_tips", self.consensus_tips, "adds the parts' tips to the "
                                    "consensus pull, which is off; set losses.consensus_coverage=1.0 (any weight "
                                    "above 0), or losses.consensus_tips=false")
        if self.pose_mixing < 1 and not self.pose_consistency:
            raise ConfigError.about("losses.pose_mixing", self.pose_mixing, "makes pose consistency partial, which "
                                    "is off (losses.pose_consistency: false)", "`losses.pose_consistency=true`, or "
                                    "`losses.pose_mixing=1`")

    def cross_view_at(self, step: int | None) -> Literal["partner", "own"]:
        """The cross view's translations at training step ``step`` (``None``: after any warm-up)."""
        if self.cross_view == "own" and step is not None and step < self.cross_view_warmup:
            return "partner"
        return self.cross_view

    @property
    def weights(self) -> dict[str, float]:
        """``{term name: weight}`` in :data:`TERMS` order."""
        return {t.name: float(getattr(self, t.name)) for t in TERM_TABLE}

    def weights_at(self, step: int | None) -> dict[str, float]:
        """:attr:`weights` at training step ``step``: with ``allocation_steps: S > 0`` the allocation pulls
        (:attr:`Term.allocation`) are scaled by ``max(0, 1 - step / S)``, so they place the parts early and
        leave the refinement to the image terms (``None``: after training, faded).

        Example:
            >>> losses = LossConfig(consensus_coverage=3.0, allocation_steps=1000)
            >>> [losses.weights_at(s)["consensus_coverage"] for s in (0, 500, 1000, None)]
            [3.0, 1.5, 0.0, 0.0]
        """
        weights = self.weights
        if self.allocation_steps <= 0:
            return weights
        scale = 0.0 if step is None else max(0.0, 1.0 - step / self.allocation_steps)
        return {t.name: weights[t.name] * scale if t.allocation else weights[t.name] for t in TERM_TABLE}


TERM_TABLE: tuple[Term, ...] = tuple(Term(f.name, f.default, **f.metadata[TERM]) for f in fields(LossConfig)
                                     if TERM in f.metadata)
"""Every term of the training objective, in logging order: :class:`LossConfig`'s weight fields."""

TERMS: tuple[str, ...] = tuple(t.name for t in TERM_TABLE)
"""The terms' names, in logging order (the ``metrics.csv`` columns after ``total``)."""


def terms_table() -> str:
    """The Markdown table of :data:`TERM_TABLE` that docs/training.md shows."""
    rows = ["| weight | symbol | paper | paper weight | what it measures | function |", "| --- | --- | --- | ---: | --- | --- |"]
    rows += [f"| `losses.{t.name}` | `{t.symbol}` | {t.source} | {t.weight:g} | {t.summary} | `{t.function.__name__}` |"
             for t in TERM_TABLE]
    return "\n".join(rows)


def quadruplet_objective(model: nn.Module, renderer: Renderer, batch: QuadrupletBatch, scene: SceneSetup,
                         losses: LossConfig, generator: torch.Generator | None = None, *,
                         smoothness_once: bool = False, antialias: bool = False,
                         step: int | None = None) -> ObjectiveOutput:
    """Evaluate the training objective on a batch of quadruplets.

    Args:
        model: a :class:`Cerberus` (possibly wrapped in DistributedDataParallel; it is called
            through the wrapper so gradients synchronise).
        renderer: the renderer backend.
        batch: ``B`` quadruplets and their ``4 B`` cameras.
        scene: albedo, light and background used to render like the dataset.
        losses: weights and switches.
        generator: random source of the pose-consistency draws.
        smoothness_once: with pose consistency, compute the smoothness loss on one image per
            quadruplet (its four images decode the same mixed latent, so their meshes are equal);
            the loss value is the same, gradients equal up to rounding (``speed.smoothness_once``).
        antialias: render with :meth:`Renderer.antialias` (``render.antialias``): visibility
            gradients for the reconstruction and silhouette terms.
        step: the training step, which decides the cross view during its warm-up
            (:meth:`LossConfig.cross_view_at`; ``None``: after the warm-up), the allocation pulls' fade and the
            deformation's hold (:meth:`Cerberus.deformation_gain`).
    """
    core = unwrap(model)
    images = batch.images.flatten(0, 1)  # (4B, 3, H, W): the stored renders, what the losses compare against
    pred: Predictions = model(batch.network_inputs.flatten(0, 1),  # the same in data.input_look
                              quadruplet_mixer(generator, losses.pose_mixing) if losses.pose_consistency else None,
                              step=step)
    parts = core.pose(pred, batch.camera)  # world frame, 4B images
    if not all(bool(torch.isfinite(t.detach()).all()) for t in (parts.local_vertices, parts.rotations,
                                                                 parts.translations)):
        nan = images.new_tensor(float("nan"))
        return ObjectiveOutput(nan, {k: nan for k in (*TERMS, "total")}, False)

    mask = background_mask(images, scene.background, losses.background_tolerance)  # (4B, 1, H, W)
    black = losses.render_background == "black"
    targets = batch.images * (1 - mask.view_as(batch.images[:, :, :1])) if black else batch.images
    cross_view = losses.cross_view_at(step)
    render = render_quadruplets(renderer, parts, batch, scene, (0.0, 0.0, 0.0) if black else scene.background,
                                viewpoint_consistency=losses.viewpoint_consistency, antialias=antialias,
                                cross_view=cross_view)
    shared_meshes = losses.pose_consistency and losses.pose_mixing == 1  # the four images decode one latent
    inputs = ObjectiveInputs(batch, pred, parts, mask, targets, render, core.dihedral, smoothness_once and shared_meshes,
                             renderer.nearest_indices, losses.cross_pulls, losses.consensus_tips, cross_view)
    weights = losses.weights_at(step)
    values = {t.name: t.value(inputs).mean() if t.always_logged or weights[t.name] != 0 else images.new_zeros(())
              for t in TERM_TABLE}
    total = sum(weights[k] * values[k] for k in TERMS if weights[k] != 0)
    total = total if isinstance(total, Tensor) else images.new_zeros(())
    terms = {k: t.detach() for k, t in values.items()} | {"total": total.detach()}
    return ObjectiveOutput(total, terms, bool(torch.isfinite(total.detach())), render.own.image.detach(),
                           render.parts_own.detach())
