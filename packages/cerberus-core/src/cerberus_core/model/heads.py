"""The three heads of Cerberus: deformation (shape), rotation and translation (section 3.2).

* :class:`ShapeHead` — object latent → shape latent (linear) → vertex displacements of all ``N``
  parts (linear), added to the template sphere scaled to ``init_scale``.
* :class:`RotationHead` — object latent → ``N`` quaternions (linear) → rotation matrices (with
  ``model.local_rotation``, beyond the paper, each part's quaternion also reads the features under its own
  keypoint map).
* :class:`TranslationHead` — up-sampled features → per part a probability map (1x1 convolution,
  spatial softmax) and a depth map (1x1 convolution); equation 1 turns their expectations into a
  3D translation by unprojecting with the known camera (:func:`unproject_expectation`).

Initialisation (chosen so that training starts from visible, well-behaved parts):

* displacements start near zero (weights ``N(0, 1e-4)``, bias 0), so every part starts as a sphere
  of radius ``init_scale`` (0.12 world units by default, about an eighth of the body height);
* quaternions start at the identity (bias ``(1, 0, 0, 0)``, weights ``N(0, 1e-3)``);
* depth maps start at ``depth_offset`` (the dataset's camera distance, so parts start near the
  world origin where the body is), the depth convolution's weights and bias being zero;
* the probability maps start as Gaussian bumps at distinct anchors on a grid over the central
  image region (:class:`TranslationHead`), with the feature convolution's default (small, random)
  initialisation on top.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import torch
from kornia.geometry.conversions import quaternion_to_rotation_matrix
from kornia.geometry.subpix import spatial_expectation2d
from torch import nn

from cerberus_core.errors import ConfigError, ShapeError
from cerberus_core.render.camera import PIXEL_CENTRE, Camera, pixel_centres

Tensor = torch.Tensor

AXIS_LOG_LIMIT = math.log(4.0)
"""``model.axis_scales``: the largest |log| of a part's scale along one axis (a quarter to four times)."""
_BOUND_EDGE = 1.0 - 1e-6  # an ellipsoid past the vertex bound is squashed to just inside it
ROOT_INIT_SCALE = 0.3
"""``model.root_part``: the root part's initial radius (world units), the NMRr baseline's one sphere's."""
ROOT_VERTEX_BOUND = 0.5
"""``model.root_part``: the bound on the root part's local coordinates (world units), the NMRr baseline's: the
half-size of the normalised object box."""


class ShapeHead(nn.Module):
    """Object latent → shape latent → per-part vertex positions in the part's local frame.

    The displacements are ``displacement_scale * (W S + b)``: a fixed output scale that acts as a
    per-layer learning rate under Adam (as the ``bias_scale`` of Kato et al.'s mesh decoder). Adam
    moves every weight by about ``lr`` per step in a coherent direction, so without it a vertex
    moves by ``lr * ||S||_1`` per step — for a 256-dimensional latent, a sizeable fraction of a
    part's radius — and the meshes turn spiky within a few steps.

    With ``recentre`` (beyond the paper, ``model.recentre``) each part's vertex mean is subtracted after the
    deformation (and the bound), so the mean of its vertices stays at its local origin and the part sits where its translation (its
    keypoint and depth) puts it: a term that wants a part elsewhere must move the keypoint, since the
    vertices can no longer shift the part back toward where the keypoint was.

    With ``axis_scales`` (beyond the paper, ``model.axis_scales``) each part's template sphere is first scaled
    along its three local axes, into an ellipsoid, by factors ``exp(L tanh(a / L))`` with ``a =
    (displacement_scale / init_scale) * (W_a S + b_a)`` (three numbers a part, zero at the start, so the parts
    start as the spheres) and ``L = ln 4`` (each axis between a quarter and four times ``init_scale``); the
    displacements are added to the ellipsoid. The output scale makes a step of Adam move a vertex as far through
    its axis as through its own displacement (``init_scale * da = displacement_scale * dW S``). A part can then
    grow long and thin along a limb as one coherent change of three numbers, where the displacement map must move
    every vertex alike and under Adam moves a few into spikes instead (issue 38; superquadric parsing predicts
    each primitive's size along its axes the same way).

    With ``root`` (beyond the paper, ``model.root_part``) part 0, the one whose keypoint starts at the image centre,
    starts as the NMRr baseline's sphere (radius :data:`ROOT_INIT_SCALE`, its coordinates bounded by
    :data:`ROOT_VERTEX_BOUND`); the other parts keep ``init_scale`` and ``vertex_bound``.

    With ``vertex_bound = b`` the coordinates are squashed instead, as in Kato et al.'s NMR decoder
    (which bounds them with a sigmoid): ``v = b * tanh(atanh(t / b) + d / b)`` for template
    coordinate ``t`` and displacement ``d``; ``v = t`` at ``d = 0``, ``v ≈ t + d`` while ``|v| << b``,
    and ``|v| <= b`` always. A single deformed sphere without the bound can grow past the camera: with
    the camera inside the mesh every pixel is covered, and the barycentric renderer, which has no
    silhouette gradient, cannot pull the surface back out (an NMRr run did this after 4,700 steps).

    Args:
        in_dim: object latent size.
        latent_dim: shape latent size.
        num_parts: ``N``.
        template: ``(V, 3)`` unit-sphere template vertices (a buffer of this module).
        init_scale: radius of the initial sphere (world units).
        displacement_scale: the output scale of the displacement map.
        vertex_bound: ``None`` or the bound ``b`` (world units, larger than ``init_scale``).
        recentre: keep each part's vertex mean at its local origin.
        axis_scales: scale each part's template along its local axes first (an ellipsoid a part).
        root: part 0 starts as the NMRr baseline's one sphere (bounded; the other parts as set).

    Example: with ``axis_scales`` an untrained head gives the template spheres; a latent that asks for a longer
    first axis stretches every part along it, as one ellipsoid:

        >>> from cerberus_core.render.templates import icosphere
        >>> head = ShapeHead(16, 8, 2, icosphere(1).vertices, init_scale=0.1, displacement_scale=0.05,
        ...                  axis_scales=True)
        >>> s = head.latent(torch.randn(3, 16))
        >>> sphere = head.deform(s)
        >>> bool(torch.equal(head.axes(s), torch.ones(3, 2, 3)))
        True
        >>> with torch.no_grad():
        ...     head.to_axes.bias.view(2, 3)[:, 0] = 2.0  # a = (0.05 / 0.1) 2 = 1: the first axis e^(ln4 tanh(1/ln4)) times
        >>> stretch = head.deform(s).amax(dim=-2) / sphere.amax(dim=-2)
        >>> [round(float(e), 2) for e in stretch[0, 0]]
        [2.35, 1.0, 1.0]
    """

    def __init__(self, in_dim: int, latent_dim: int, num_parts: int, template: Tensor, init_scale: float,
                 displacement_scale: float = 1.0, vertex_bound: float | None = None, recentre: bool = False,
                 axis_scales: bool = False, root: bool = False) -> None:
        super().__init__()
        self.recentre = bool(recentre)
        self.num_parts = num_parts
        self.num_vertices = template.shape[0]
        self.displacement_scale = float(displacement_scale)
        self.to_latent = nn.Linear(in_dim, latent_dim)
        self.to_displacement = nn.Linear(latent_dim, num_parts * self.num_vertices * 3)
        nn.init.normal_(self.to_displacement.weight, std=1e-4)
        nn.init.zeros_(self.to_displacement.bias)
        self.axis_rate = self.displacement_scale / float(init_scale)
        self.to_axes: nn.Linear | None = None  # built only when asked, so the paper's models keep their tensors
        if axis_scales:  # without drawing from the random stream: every other weight starts as without the switch
            self.to_axes = nn.utils.skip_init(nn.Linear, latent_dim, num_parts * 3)
            nn.init.zeros_(self.to_axes.weight)
            nn.init.zeros_(self.to_axes.bias)
        self.register_buffer("template", template.float() * init_scale, persistent=False)
        self.vertex_bound = None if vertex_bound is None else float(vertex_bound)
        if self.vertex_bound is not None and not self.vertex_bound > init_scale:
            raise ConfigError.about("vertex_bound", vertex_bound, f"must exceed init_scale ({init_scale})",
                                    "a bound larger than the template's scale, or `vertex_bound=None`")
        self.register_buffer("root_template", template.float() * ROOT_INIT_SCALE if root else None, persistent=False)

    def latent(self, object_latent: Tensor) -> Tensor:
        """``(B, in_dim)`` → ``(B, latent_dim)`` shape latent ``S``."""
        return self.to_latent(object_latent)

    def axes(self, shape_latent: Tensor, gain: float = 1.0) -> Tensor:
        """``(B, latent_dim)`` shape latent → ``(B, N, 3)`` each part's scale along its local axes (unitless,
        between 1/4 and 4; all ones without ``axis_scales``, or at ``gain`` 0)."""
        n = shape_latent.shape[0]
        if self.to_axes is None:
            return shape_latent.new_ones(n, self.num_parts, 3)
        a = (self.axis_rate * gain) * self.to_axes(shape_latent).view(n, self.num_parts, 3)
        return torch.exp(AXIS_LOG_LIMIT * torch.tanh(a / AXIS_LOG_LIMIT))

    def deform(self, shape_latent: Tensor, gain: float = 1.0) -> Tensor:
        """``(B, latent_dim)`` shape latent → ``(B, N, V, 3)`` deformed part vertices (local frame); ``gain``
        scales the displacements and the axis scales' logarithms (0: the template spheres,
        ``model.deformation_warmup``)."""
        scale = self.displacement_scale * gain if gain != 1.0 else self.displacement_scale
        disp = scale * self.to_displacement(shape_latent).view(-1, self.num_parts, self.num_vertices, 3)
        axes = None if self.to_axes is None else self.axes(shape_latent, gain)[:, :, None]  # (B, N, 1, 3)
        if self.root_template is None:
            local = bounded(self.template if axes is None else self.template * axes, disp, self.vertex_bound)
        else:  # model.root_part: part 0 is NMRr's sphere under NMRr's bound, the other parts as set
            root = self.root_template if axes is None else self.root_template * axes[:, :1]
            rest = self.template if axes is None else self.template * axes[:, 1:]
            local = torch.cat([bounded(root, disp[:, :1], ROOT_VERTEX_BOUND),
                               bounded(rest, disp[:, 1:], self.vertex_bound)], dim=1)
        return local - local.mean(dim=-2, keepdim=True) if self.recentre else local


def bounded(template: Tensor, displacement: Tensor, bound: float | None) -> Tensor:
    """Template coordinates plus displacements (``(..., V, 3)``, world units, broadcast against each other), as they
    are (``bound=None``) or squashed into ``(-bound, bound)`` as Kato et al.'s NMR decoder bounds them:
    ``b tanh(atanh(t / b) + d / b)``, which is ``t`` at ``d = 0`` and about ``t + d`` while ``|t + d| << b``.

    Example:
        >>> t, d = torch.tensor([0.1, 0.1]), torch.tensor([0.0, 5.0])
        >>> [round(float(v), 4) for v in bounded(t, d, 0.5)], [round(float(v), 4) for v in bounded(t, d, None)]
        ([0.1, 0.5], [0.1, 5.1])
    """
    if bound is None:
        return template + displacement
    return bound * torch.tanh(torch.atanh((template / bound).clamp(-_BOUND_EDGE, _BOUND_EDGE)) + displacement / bound)


class RotationHead(nn.Module):
    """Object latent → ``N`` unit quaternions ``(w, x, y, z)`` → ``N`` rotation matrices.

    With ``local_dim`` (beyond the paper, ``model.local_rotation``) each part's quaternion also reads the features
    under its own keypoint map: ``q_k = W_k o + b_k + A_k f_k``, with ``o`` the object latent, ``f_k`` the part's
    ``local_dim`` features (:func:`features_under`) and ``A_k`` a ``(local_dim, 4)`` map of its own, zero at the start
    (a plain tensor of zeros, drawn from no random stream, so the head starts as without it, bit for bit). The
    object latent is the average of a 2x2 map of the whole image, one vector for all ``N`` parts, so how each part
    is turned must be read out of the same global summary; ``f_k`` is where the part is (issue 38: the parts sit
    on the limbs in the image and point the wrong way in depth).

    Args:
        in_dim: object latent size.
        num_parts: ``N``.
        local_dim: ``None`` (the paper) or the channels of the features each part reads under its map.
    """

    def __init__(self, in_dim: int, num_parts: int, local_dim: int | None = None) -> None:
        super().__init__()
        self.num_parts = num_parts
        self.linear = nn.Linear(in_dim, num_parts * 4)
        nn.init.normal_(self.linear.weight, std=1e-3)
        with torch.no_grad():
            self.linear.bias.copy_(torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat(num_parts))
        self.local = None if local_dim is None else nn.Parameter(torch.zeros(num_parts, local_dim, 4))

    def forward(self, object_latent: Tensor, local: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Returns ``quaternions`` ``(B, N, 4)`` (unit, real part first) and ``rotations`` ``(B, N, 3, 3)``;
        ``local`` ``(B, N, local_dim)``, each part's features under its map, is read only with ``local_dim``."""
        q = self.linear(object_latent).view(-1, self.num_parts, 4)
        if self.local is not None:
            if local is None:
                raise ShapeError("RotationHead: built with local_dim, so it needs each part's features under its "
                                 "keypoint map (B, N, local_dim) as its second argument (features_under)")
            q = q + torch.einsum("bnc,ncq->bnq", local, self.local)
        q = nn.functional.normalize(q, dim=-1, eps=1e-8)
        return q, quaternion_to_rotation_matrix(q)

    def identity(self, object_latent: Tensor) -> tuple[Tensor, Tensor]:
        """What :meth:`forward` returns for ``model.rotation: none``, without running the layer: identity
        quaternions ``(B, N, 4)`` and rotations ``(B, N, 3, 3)``, constants (no parameter takes part).

        >>> q, r = RotationHead(8, 2).identity(torch.zeros(3, 8))
        >>> q.shape, r.shape, bool((r == torch.eye(3)).all())
        (torch.Size([3, 2, 4]), torch.Size([3, 2, 3, 3]), True)
        """
        b, like = object_latent.shape[0], self.linear.bias
        q = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=like.dtype, device=like.device).expand(b, self.num_parts, 4)
        return q, torch.eye(3, dtype=like.dtype, device=like.device).expand(b, self.num_parts, 3, 3)


@dataclass
class KeypointMaps:
    """Per-part maps on the input pixel grid and their expectations (equation 1, before unprojection).

    Attributes:
        prob: ``(B, N, H, W)`` probability maps ``p^k`` (each sums to 1).
        depth_cells: ``(B, N, h, w)`` the depth maps on the grid they were predicted on (world
            units; ``(h, w) = (H, W)`` when no up-sampling took place); :attr:`depth_map` is them
            up-sampled bilinearly to the pixel grid.
        uv: ``(B, N, 2)`` expected pixel coordinates ``(u, v) = (sum x p, sum y p)`` with pixel
            centres at ``j + 0.5`` (the :mod:`cerberus_core.render.camera` convention).
        depth: ``(B, N)`` expected depth ``sum d p`` (world units).
    """

    prob: Tensor
    depth_cells: Tensor
    uv: Tensor
    depth: Tensor

    @property
    def depth_map(self) -> Tensor:
        """``(B, N, H, W)`` depth maps ``d^k`` on the pixel grid (world units), up-sampled when read
        (training reads only :attr:`depth`, which :func:`expectation` takes on the cells)."""
        return upsample_bilinear(self.depth_cells, tuple(self.prob.shape[-2:]))


def anchor_grid(num_parts: int, spread: float) -> Tensor:
    """``(N, 2)`` initial keypoints in normalised image coordinates ``[-1, 1]`` (x right, y down):
    the first ``N`` points of a ``ceil(sqrt(N))``-square grid spanning ``[-spread, spread]``, ordered
    from the centre outwards (so small ``N`` stay central; ``N = 1`` is the centre)."""
    side = math.ceil(math.sqrt(num_parts))
    ticks = torch.linspace(-spread, spread, side) if side > 1 else torch.zeros(1)
    grid = torch.stack(torch.meshgrid(ticks, ticks, indexing="xy"), -1).reshape(-1, 2)
    order = torch.argsort(grid.norm(dim=-1) + 1e-3 * torch.arange(len(grid)), stable=True)
    return grid[order[:num_parts]]


class TranslationHead(nn.Module):
    """Per-part probability and depth maps from the decoder features.

    The probability-map logits are a linear map (1x1 convolution) of the features plus a linear map
    of the pixel coordinates ``(x, y, x^2, y^2)`` (normalised to ``[-1, 1]``), whose weights start as
    a Gaussian bump of width ``anchor_width`` (default: ``anchor_spread``) at a per-part anchor
    (:func:`anchor_grid`): parts start at distinct image locations, so the background loss pulls each
    towards the nearest body region instead of all towards the same one. Every weight stays
    learnable; ``anchor_spread: 0`` starts all parts at the image centre with no coordinate term. A
    bump as wide as the grid, cut off by the image's border, starts its part between the anchor and
    the centre (at 0.32-0.35 of the half-image for any spread from 0.4 to 0.8); a narrower ``anchor_width``
    starts it on its anchor, so a wider grid really spreads the parts.

    Args:
        in_channels: decoder feature channels.
        num_parts: ``N``.
        depth_offset: added to the depth maps (world units; the typical camera distance).
        anchor_spread: half-extent of the anchor grid in normalised image coordinates.
        anchor_width: the bumps' standard deviation in normalised image coordinates (``None``:
            ``anchor_spread``).
        body_depth_from: ``None`` (the paper) or the size of the image's global latent: one depth shift per
            image, a linear map of that latent (zero at the start), is added to every part's depth maps, so
            where the whole body stands along the view is read from the whole image and not from the
            features under each keypoint (``model.body_depth``; beyond the paper, issue 38).
    """

    def __init__(self, in_channels: int, num_parts: int, depth_offset: float, anchor_spread: float = 0.4,
                 anchor_width: float | None = None, body_depth_from: int | None = None) -> None:
        super().__init__()
        self.logits = nn.Conv2d(in_channels, num_parts, 1)
        self.coords = nn.Linear(4, num_parts, bias=False)
        self.depth = nn.Conv2d(in_channels, num_parts, 1)
        nn.init.zeros_(self.depth.weight)
        nn.init.zeros_(self.depth.bias)
        self.depth_offset = float(depth_offset)
        self.body_depth = None if body_depth_from is None else nn.Linear(body_depth_from, 1)
        if self.body_depth is not None:
            nn.init.zeros_(self.body_depth.weight)
            nn.init.zeros_(self.body_depth.bias)
        with torch.no_grad():
            if anchor_spread > 0:
                centre = anchor_grid(num_parts, anchor_spread)
                width = anchor_spread if anchor_width is None else anchor_width
                inv = 1.0 / (2 * width**2)  # -(p - c)^2 / (2 s^2), constant dropped
                self.coords.weight.copy_(torch.cat([2 * inv * centre, -inv * torch.ones(num_parts, 2)], 1))
            else:
                self.coords.weight.zero_()

    def forward(self, features: Tensor, size: tuple[int, int], latent: Tensor | None = None) -> KeypointMaps:
        """``features`` ``(B, C, h, w)`` → :class:`KeypointMaps` on an ``size = (H, W)`` pixel grid; ``latent``
        ``(B, L)``, the image's global latent, is read only with ``body_depth_from``."""
        h, w = features.shape[-2:]
        # Feature-cell centres in [-1, 1], x right and y down (rows): the pixel-centre rule of
        # render.camera.pixel_centres, whose y grows up (0 - py, not -py: the same bits, +0.0 included).
        xs, py = pixel_centres(h, w, features.dtype, features.device)
        ys = 0.0 - py
        gy, gx = torch.meshgrid(ys, xs, indexing="ij")
        coords = torch.stack([gx, gy, gx.square(), gy.square()], -1)  # (h, w, 4)
        logits = self.logits(features) + self.coords(coords).permute(2, 0, 1).unsqueeze(0)
        prob = spatial_softmax(upsample_bilinear(logits, tuple(size)))
        depth = self.depth(features) + self.depth_offset
        if self.body_depth is not None:
            if latent is None:
                raise ShapeError("TranslationHead: built with body_depth_from, so it needs the image's global latent "
                                 "(B, L) as its third argument")
            depth = depth + self.body_depth(latent).view(-1, 1, 1, 1)  # the same shift for every part and cell
        return expectation(prob, depth)


@functools.lru_cache(maxsize=16)
def bilinear_matrix(n_in: int, n_out: int, dtype: torch.dtype, device: torch.device) -> Tensor:
    """``(n_out, n_in)`` the weights of 1-D linear up-sampling from ``n_in`` to ``n_out`` samples, as
    ``torch.nn.functional.interpolate(mode="linear", align_corners=False)`` computes them (row ``o``
    holds the two weights of output sample ``o``; taken from that function, so they are its own)."""
    eye = torch.eye(n_in, dtype=dtype, device=device).unsqueeze(0)  # (1, n_in channels, n_in samples)
    return nn.functional.interpolate(eye, size=n_out, mode="linear", align_corners=False)[0].T.contiguous()


def upsample_bilinear(maps: Tensor, size: tuple[int, int]) -> Tensor:
    """``(..., h, w)`` → ``(..., H, W)``: bilinear up-sampling (``align_corners=False``) as two
    products with fixed interpolation matrices, ``L_y maps L_x^T``; the values of
    ``nn.functional.interpolate(mode="bilinear")`` up to float rounding, with a backward pass of two
    more products instead of its scatter. Returns ``maps`` itself when ``(h, w) == size``."""
    h, w = maps.shape[-2:]
    if (h, w) == tuple(size):
        return maps
    ly = bilinear_matrix(h, size[0], maps.dtype, maps.device)  # (H, h)
    lx = bilinear_matrix(w, size[1], maps.dtype, maps.device)  # (W, w)
    return ly @ (maps @ lx.T)


def spatial_softmax(logits: Tensor) -> Tensor:
    """Softmax over each ``(H, W)`` map of ``(B, N, H, W)`` logits: the values of kornia's
    ``spatial_softmax2d`` bit for bit, without its division by a temperature of 1 (two passes over
    the maps, forward and backward)."""
    b, n, h, w = logits.shape
    return nn.functional.softmax(logits.reshape(b, n, h * w), dim=-1).view(b, n, h, w)


def expectation(prob: Tensor, depth_cells: Tensor) -> KeypointMaps:
    """Expected pixel coordinates and depth under probability maps (the sum in equation 1).

    The depth maps may lie on a coarser grid than ``prob`` (as the translation head predicts them):
    they stand for their bilinear up-sampling ``L_y d L_x^T`` (:func:`upsample_bilinear`), and since
    ``sum_HW p (L_y d L_x^T) = sum_hw d (L_y^T p L_x)`` the expected depth is taken on the cells,
    without up-sampling the depth maps (equal to the pixel-grid sum up to rounding).

    Args:
        prob: ``(B, N, H, W)`` maps summing to 1.
        depth_cells: ``(B, N, h, w)`` depth maps, ``(h, w)`` = ``(H, W)`` or coarser.
    """
    uv = spatial_expectation2d(prob, normalized_coordinates=False) + PIXEL_CENTRE  # cell j is centred at j + 0.5
    weight = cell_shares(prob, tuple(depth_cells.shape[-2:]))
    return KeypointMaps(prob, depth_cells, uv, (weight * depth_cells).sum(dim=(-2, -1)))


def cell_shares(prob: Tensor, cells: tuple[int, int]) -> Tensor:
    """``(B, N, h, w)`` each cell's share of the probability maps ``prob`` ``(B, N, H, W)``: ``L_y^T p L_x``, the
    adjoint of the bilinear up-sampling from the ``cells = (h, w)`` grid to the pixels (:func:`upsample_bilinear`),
    so that ``sum_hw share * m = sum_HW p * upsample(m)`` for any map ``m`` on the cells; ``prob`` itself when the
    grids are one. Each share map sums to 1 as ``p`` does (a linear up-sampling keeps constants).

    Example:
        >>> p = torch.zeros(1, 1, 8, 8)
        >>> p[0, 0, 3, 4] = 1.0  # all the mass on one pixel
        >>> share = cell_shares(p, (4, 4))
        >>> share.shape, round(float(share.sum()), 6), bool((share >= 0).all())
        (torch.Size([1, 1, 4, 4]), 1.0, True)
    """
    h, w = cells
    height, width = prob.shape[-2:]
    if (h, w) == (height, width):
        return prob
    return bilinear_matrix(h, height, prob.dtype, prob.device).T @ (prob @ bilinear_matrix(w, width, prob.dtype,
                                                                                             prob.device))


def features_under(prob: Tensor, features: Tensor) -> Tensor:
    """``(B, N, C)`` what each part's probability map reads of the features: the expectation under ``p_k``
    ``(B, N, H, W)`` of the features ``(B, C, h, w)`` up-sampled bilinearly to the pixels, taken on the cells
    (:func:`cell_shares`), as equation 1 takes the part's depth (``model.local_rotation``; beyond the paper).

    Example:
        >>> features = torch.arange(2 * 4 * 4, dtype=torch.float32).view(1, 2, 4, 4)
        >>> p = torch.full((1, 1, 8, 8), 1 / 64)  # uniform: the mean of the up-sampled features
        >>> features_under(p, features).shape
        torch.Size([1, 1, 2])
        >>> bool(torch.allclose(features_under(p, features)[0, 0], upsample_bilinear(features, (8, 8)).mean((-2, -1))[0]))
        True
    """
    shares = cell_shares(prob, tuple(features.shape[-2:]))
    return torch.einsum("bnhw,bchw->bnc", shares, features)


def unproject_expectation(maps: KeypointMaps, camera: Camera, *, to_world: bool) -> Tensor:
    """Equation 1: ``T_k = pi^{-1}(sum x p, sum y p, sum d p)``.

    Args:
        maps: keypoint maps of ``B`` images.
        camera: the ``B`` cameras that took them (image size must match the maps).
        to_world: world coordinates, or the camera frame.
    Returns:
        ``(B, N, 3)`` part translations.
    """
    h, w = maps.prob.shape[-2:]
    if (camera.height, camera.width) != (h, w):
        raise ShapeError(f"camera image size {camera.height}x{camera.width} does not match the maps' {h}x{w}; "
                         "build the camera with the size of the images given to the model")
    return camera.unproject(maps.uv, maps.depth, to_world=to_world)
