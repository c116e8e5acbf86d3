"""Perspective pinhole camera: look-at placement and its inverse, orbits, projection and unprojection,
and the pixel-centre rule (:func:`pixel_centres`).

Conventions (used everywhere in the toolkit):

* World frame: right-handed, +Y up. At azimuth 0 and elevation 0 the camera sits on the +Z axis
  and looks at the origin; azimuth turns the camera towards +X, elevation lifts it towards +Y.
* Camera frame (OpenGL style): +X right, +Y up, the camera looks along -Z. A point in front of the
  camera has ``z_cam < 0``; its *depth* is ``d = -z_cam > 0`` (world units).
* Clip space: ``x_clip = f / aspect * x_cam``, ``y_clip = f * y_cam``, ``w_clip = d``, with
  ``f = 1 / tan(fov_y / 2)``; ``z_clip`` follows OpenGL with the camera's near and far planes. NDC is
  ``clip[..., :2] / w`` in ``[-1, 1]`` with +y up.
* Pixels: ``u`` (column) grows right, ``v`` (row) grows down, pixel ``(row i, col j)`` has its centre
  at ``(u, v) = (j + 0.5, i + 0.5)``. The image spans ``u in [0, W]``, ``v in [0, H]``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from cerberus_core.errors import RenderInputError, ShapeError
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor


def _as_batch(x: float | Tensor, batch: int | None = None, *, dtype=torch.float32, device=None) -> Tensor:
    t = torch.as_tensor(x, dtype=dtype, device=device)
    if t.ndim == 0:
        t = t.reshape(1)
    if batch is not None and t.shape[0] == 1 and batch > 1:
        t = t.expand(batch)
    return t


def look_at_rotation(eye: Tensor, target: Tensor, up: Tensor | None = None) -> Tensor:
    """World→camera rotation for a camera at ``eye`` looking at ``target``.

    Args:
        eye: ``(B, 3)`` camera centres (world units).
        target: ``(B, 3)`` points looked at.
        up: ``(B, 3)`` or ``(3,)`` world up direction (default +Y).

    Returns:
        ``(B, 3, 3)`` rotation ``R`` with rows the camera's x, y, z axes in world coordinates, so
        ``x_cam = R @ (x_world - eye)``.
    """
    if up is None:
        up = torch.tensor([0.0, 1.0, 0.0], dtype=eye.dtype, device=eye.device)
    up = up.expand_as(eye)
    z_axis = torch.nn.functional.normalize(eye - target, dim=-1)  # camera looks along -z
    x_axis = torch.linalg.cross(up, z_axis, dim=-1)
    # Looking straight down (up): use -Z (+Z) as the up hint, the limit of elevations approaching
    # +-90 degrees at azimuth 0, so the image does not flip at the pole.
    degenerate = x_axis.norm(dim=-1, keepdim=True) < 1e-6
    alt = torch.zeros_like(eye)
    alt[..., 2] = torch.where(z_axis[..., 1] > 0, -1.0, 1.0)
    x_axis = torch.where(degenerate, torch.linalg.cross(alt, z_axis, dim=-1), x_axis)
    x_axis = torch.nn.functional.normalize(x_axis, dim=-1)
    y_axis = torch.linalg.cross(z_axis, x_axis, dim=-1)
    return torch.stack([x_axis, y_axis, z_axis], dim=-2)


def spherical_to_eye(azimuth_deg: Tensor, elevation_deg: Tensor, distance: Tensor) -> Tensor:
    """Camera centre on a sphere around the origin.

    Args:
        azimuth_deg, elevation_deg, distance: ``(B,)`` degrees, degrees, world units.

    Returns:
        ``(B, 3)`` eye positions ``d * (cos(el) sin(az), sin(el), cos(el) cos(az))``.
    """
    az = torch.deg2rad(azimuth_deg)
    el = torch.deg2rad(elevation_deg)
    return torch.stack(
        [distance * torch.cos(el) * torch.sin(az), distance * torch.sin(el), distance * torch.cos(el) * torch.cos(az)],
        dim=-1,
    )


PIXEL_CENTRE = 0.5
"""Pixel ``j`` spans ``[j, j + 1)`` in pixel units and is sampled at ``j + PIXEL_CENTRE`` (module
docstring, "Pixels"): the offset every pixel-unit computation uses (keypoint expectations, the
backends' bounding boxes)."""

BBOX_EPS = 1e-3
"""Widening of each triangle's pixel bounding box, in pixels, in every backend's rasterizer, so that
rounding never drops a covered pixel; coverage itself is decided by the edge functions."""


def centre_range(lo: Tensor, hi: Tensor, size: int) -> tuple[Tensor, Tensor]:
    """Inclusive index range ``(first, last)`` (int64) of the pixel centres ``k + PIXEL_CENTRE``
    inside ``[lo, hi]`` (pixel units, any shape), widened by :data:`BBOX_EPS` and clipped to
    ``0 .. size - 1``; empty where ``first > last``. Clamp huge coordinates before calling."""
    first = torch.ceil(lo - PIXEL_CENTRE - BBOX_EPS).clamp_min(0).long()
    last = torch.floor(hi - PIXEL_CENTRE + BBOX_EPS).clamp_max(size - 1).long()
    return first, last


def pixel_centres(height: int, width: int, dtype: torch.dtype = torch.float32,
                  device: torch.device | str | None = None) -> tuple[Tensor, Tensor]:
    """NDC coordinates of the pixel centres (module docstring, "Pixels"; the rasterization rule of
    :mod:`cerberus_core.render.interface`): the one place they are computed (the backends'
    rasterizers, the shared shading and anti-aliasing all take them from here, so they agree bit for
    bit in every dtype).

    Returns:
        ``px`` ``(W,)`` = ``2 (j + 0.5) / W - 1`` per column and ``py`` ``(H,)`` = ``1 - 2 (i + 0.5) / H``
        per row, in ``dtype``.
    """
    cols = torch.arange(width, device=device).to(dtype)
    rows = torch.arange(height, device=device).to(dtype)
    return (2.0 * cols + 1.0) / width - 1.0, 1.0 - (2.0 * rows + 1.0) / height


@dataclass
class Camera:
    """A batch of perspective pinhole cameras sharing one image size.

    Attributes:
        rotation: ``(B, 3, 3)`` world→camera rotation ``R``.
        translation: ``(B, 3)`` world→camera translation ``t``: ``x_cam = R x_world + t``.
        fov_y_deg: ``(B,)`` vertical field of view in degrees.
        height, width: image size in pixels.
        near, far: clipping distances (world units, measured as depth ``d``). Triangles with a vertex
            nearer than ``near`` are not drawn.
    """

    rotation: Tensor
    translation: Tensor
    fov_y_deg: Tensor
    height: int
    width: int
    near: float = 0.05
    far: float = 100.0

    def __post_init__(self) -> None:
        b = check_shapes("Camera", rotation=(self.rotation, "B 3 3"), translation=(self.translation, "B 3"))["B"]
        self.fov_y_deg = _as_batch(self.fov_y_deg, b, dtype=self.rotation.dtype, device=self.rotation.device)
        check_shapes("Camera (fov_y_deg: a scalar or one per camera)", fov_y_deg=(self.fov_y_deg, f"{b}"))
        if not bool(((self.fov_y_deg > 0) & (self.fov_y_deg < 180)).all()):
            raise RenderInputError("Camera.fov_y_deg must lie strictly between 0 and 180 degrees; e.g. "
                                   "`fov_y_deg=default_fov_for(distance)`")
        if self.height <= 0 or self.width <= 0:
            raise RenderInputError(f"Camera image size must be positive, got {self.height}x{self.width}; pass a "
                                   "`height` and `width` (or `image_size`) of 1 or more")
        if not 0 < self.near < self.far:
            raise RenderInputError(f"Camera needs 0 < near < far, got near={self.near}, far={self.far}; set `near` "
                                   "above 0 and `far` above `near`")

    # ------------------------------------------------------------------ construction
    @classmethod
    def look_at(
        cls,
        azimuth_deg: float | Tensor,
        elevation_deg: float | Tensor,
        distance: float | Tensor,
        *,
        fov_y_deg: float | Tensor = 30.0,
        image_size: int | tuple[int, int] = 64,
        target: Tensor | None = None,
        near: float = 0.05,
        far: float = 100.0,
        device: torch.device | str | None = None,
    ) -> Camera:
        """Cameras on a sphere around ``target`` (default the origin), looking at it, +Y up.

        Scalars broadcast against tensors; the batch size is the largest of the inputs.
        """
        tensors = [torch.as_tensor(x, dtype=torch.float32, device=device).reshape(-1)
                   for x in (azimuth_deg, elevation_deg, distance)]
        b = max(t.shape[0] for t in tensors)
        az, el, dist = (t.expand(b) if t.shape[0] == 1 else t for t in tensors)
        if not all(t.shape[0] == b for t in (az, el, dist)):
            raise ShapeError("look_at: azimuth, elevation and distance must be scalars or share one batch size; pass "
                             "scalars or tensors of one length")
        if bool((dist <= 0).any()):
            raise RenderInputError("look_at: distance must be positive; place the camera at `distance` > 0 from its "
                                   "target")
        tgt = torch.zeros(b, 3, device=az.device) if target is None else target.to(az).reshape(-1, 3).expand(b, 3)
        eye = spherical_to_eye(az, el, dist) + tgt
        rot = look_at_rotation(eye, tgt)
        trans = -(rot @ eye.unsqueeze(-1)).squeeze(-1)
        h, w = (image_size, image_size) if isinstance(image_size, int) else image_size
        return cls(rot, trans, fov_y_deg, int(h), int(w), near, far)

    def spherical(self) -> tuple[Tensor, Tensor, Tensor]:
        """``(azimuth_deg, elevation_deg, distance)``, each ``(B,)``, of look-at cameras aimed at the
        origin: the inverse of :meth:`look_at`."""
        c = self.center
        dist = c.norm(dim=-1)
        el = torch.rad2deg(torch.asin((c[:, 1] / dist).clamp(-1, 1)))
        az = torch.rad2deg(torch.atan2(c[:, 0], c[:, 2]))
        return az, el, dist

    def orbit(self, azimuth_offsets_deg: Sequence[float] | Tensor) -> Camera:
        """Cameras at this camera's elevation, distance and fov, turned about the origin by each
        azimuth offset.

        Args:
            azimuth_offsets_deg: ``(n,)`` offsets added to the azimuth of this one camera (batch 1).
        Returns:
            ``n`` cameras.
        """
        if self.batch_size != 1:
            raise ShapeError(f"Camera.orbit: expected one camera, got {self.batch_size}; orbit `camera.index([i])`")
        az, el, dist = self.spherical()
        offsets = torch.as_tensor(azimuth_offsets_deg, dtype=az.dtype, device=az.device).reshape(-1)
        return Camera.look_at(az + offsets, el.expand_as(offsets), dist.expand_as(offsets),
                              fov_y_deg=self.fov_y_deg.expand_as(offsets), image_size=(self.height, self.width),
                              near=self.near, far=self.far, device=self.device)

    @property
    def batch_size(self) -> int:
        return self.rotation.shape[0]

    @property
    def device(self) -> torch.device:
        return self.rotation.device

    @property
    def center(self) -> Tensor:
        """``(B, 3)`` camera centres in world coordinates."""
        return -(self.rotation.transpose(-1, -2) @ self.translation.unsqueeze(-1)).squeeze(-1)

    @property
    def focal(self) -> Tensor:
        """``(B,)`` normalised focal length ``f = 1 / tan(fov_y / 2)``."""
        return 1.0 / torch.tan(torch.deg2rad(self.fov_y_deg) / 2)

    def to(self, device: torch.device | str) -> Camera:
        return Camera(self.rotation.to(device), self.translation.to(device), self.fov_y_deg.to(device),
                      self.height, self.width, self.near, self.far)

    def index(self, idx: Tensor | slice | list[int]) -> Camera:
        """A sub-batch of cameras."""
        return Camera(self.rotation[idx], self.translation[idx], self.fov_y_deg[idx],
                      self.height, self.width, self.near, self.far)

    @staticmethod
    def cat(cameras: list[Camera]) -> Camera:
        """Concatenate camera batches that share image size and clipping planes."""
        first = cameras[0]
        for c in cameras[1:]:
            if (c.height, c.width, c.near, c.far) != (first.height, first.width, first.near, first.far):
                raise RenderInputError("Camera.cat: cameras must share image size and near/far planes; concatenate "
                                       "cameras made with one `image_size`, `near` and `far`")
        return Camera(torch.cat([c.rotation for c in cameras]), torch.cat([c.translation for c in cameras]),
                      torch.cat([c.fov_y_deg for c in cameras]), first.height, first.width, first.near, first.far)

    # ------------------------------------------------------------------ transforms
    def _pose_as(self, like: Tensor) -> tuple[Tensor, Tensor]:
        """The rotation and translation in the dtype of ``like``: the transforms take points of any float dtype
        (float64 geometry with a float32 camera, as the render ops do), in the points' dtype."""
        return self.rotation.to(like.dtype), self.translation.to(like.dtype)

    def world_to_camera(self, points: Tensor) -> Tensor:
        """``(B, N, 3)`` world points → ``(B, N, 3)`` camera-frame points (in the points' dtype)."""
        rotation, translation = self._pose_as(points)
        return points @ rotation.transpose(-1, -2) + translation.unsqueeze(-2)

    def camera_to_world(self, points: Tensor) -> Tensor:
        """``(B, N, 3)`` camera-frame points → ``(B, N, 3)`` world points (in the points' dtype)."""
        rotation, translation = self._pose_as(points)
        return (points - translation.unsqueeze(-2)) @ rotation

    def rotation_to_world(self, rot_cam: Tensor) -> Tensor:
        """Express rotations given in the camera frame in the world frame.

        Args:
            rot_cam: ``(B, ..., 3, 3)`` rotations acting on camera-frame vectors.
        Returns:
            ``(B, ..., 3, 3)`` ``R^T rot_cam`` (maps object-local vectors to world vectors).
        """
        r = self.rotation.reshape(self.batch_size, *([1] * (rot_cam.ndim - 3)), 3, 3)
        return r.transpose(-1, -2) @ rot_cam

    def camera_to_clip(self, points: Tensor) -> Tensor:
        """``(B, N, 3)`` camera-frame points → ``(B, N, 4)`` homogeneous clip coordinates."""
        f = self.focal.reshape(-1, 1)
        aspect = self.width / self.height
        x, y, z = points.unbind(-1)
        n, fa = self.near, self.far
        z_clip = (fa + n) / (n - fa) * z + 2 * fa * n / (n - fa)
        return torch.stack([x * f / aspect, y * f, z_clip, -z], dim=-1)

    def world_to_clip(self, points: Tensor) -> Tensor:
        """``(B, N, 3)`` world points → ``(B, N, 4)`` clip coordinates."""
        return self.camera_to_clip(self.world_to_camera(points))

    def ndc_to_pixel(self, ndc: Tensor) -> Tensor:
        """``(..., 2)`` NDC (x right, y up, in [-1, 1]) → ``(..., 2)`` pixel ``(u, v)``."""
        u = (ndc[..., 0] + 1) * 0.5 * self.width
        v = (1 - ndc[..., 1]) * 0.5 * self.height
        return torch.stack([u, v], dim=-1)

    def pixel_to_ndc(self, uv: Tensor) -> Tensor:
        """``(..., 2)`` pixel ``(u, v)`` → ``(..., 2)`` NDC."""
        x = uv[..., 0] / self.width * 2 - 1
        y = 1 - uv[..., 1] / self.height * 2
        return torch.stack([x, y], dim=-1)

    def project(self, points: Tensor) -> tuple[Tensor, Tensor]:
        """World points to pixels.

        Args:
            points: ``(B, N, 3)`` world coordinates.
        Returns:
            ``uv`` ``(B, N, 2)`` pixel coordinates and ``depth`` ``(B, N)`` (world units, > 0 in front).
        """
        clip = self.world_to_clip(points)
        w = clip[..., 3]
        ndc = clip[..., :2] / w.unsqueeze(-1)
        return self.ndc_to_pixel(ndc), w

    def unproject(self, uv: Tensor, depth: Tensor, *, to_world: bool = True) -> Tensor:
        """Pixels plus depth back to 3D points: the inverse of :meth:`project`.

        Args:
            uv: ``(B, N, 2)`` pixel coordinates (continuous; centres at ``j + 0.5``).
            depth: ``(B, N)`` depth ``d = -z_cam`` (world units).
            to_world: return world coordinates (default) or camera-frame coordinates.
        Returns:
            ``(B, N, 3)`` points.
        """
        ndc = self.pixel_to_ndc(uv)
        f = self.focal.reshape(-1, 1)
        aspect = self.width / self.height
        x_cam = ndc[..., 0] * depth * aspect / f
        y_cam = ndc[..., 1] * depth / f
        cam = torch.stack([x_cam, y_cam, -depth], dim=-1)
        return self.camera_to_world(cam) if to_world else cam

    def rays(self, uv: Tensor) -> Tensor:
        """``(B, N, 3)`` unit world directions from each camera's centre through the pixels ``uv`` ``(B, N, 2)``:
        the rays :func:`triangulate` intersects."""
        ends = self.unproject(uv, torch.ones_like(uv[..., 0]))
        return torch.nn.functional.normalize(ends - self.center.unsqueeze(1), dim=-1)

    def view_direction(self) -> Tensor:
        """``(B, 3)`` unit vectors from the origin of the world towards each camera centre, i.e. the
        direction *towards* a light that follows the camera (world coordinates)."""
        # The camera's +z axis (pointing back towards the viewer) in world coordinates.
        return self.rotation[:, 2, :]


def triangulate(origins: Tensor, directions: Tensor, ridge: float = 1e-6) -> Tensor:
    """The least-squares intersection of ``K`` rays per point: the point whose summed squared distance to the
    rays is least (for two rays, the midpoint of their closest points).

    Args:
        origins: ``(..., K, 3)`` each ray's start (a camera's centre), world units.
        directions: ``(..., K, N, 3)`` unit directions, ``N`` points seen by each of the ``K`` rays.
        ridge: a small pull toward the world origin, so rays that are (nearly) parallel, whose intersection is
            undefined along them, still give a finite point: the origin's side of the ray (the body stands there).
    Returns:
        ``(..., N, 3)`` world points.

    Example:
        >>> o = torch.tensor([[0.0, 0.0, 2.0], [2.0, 0.0, 0.0]])          # two cameras
        >>> p = torch.tensor([[0.1, 0.2, -0.1]])                           # one point
        >>> d = torch.nn.functional.normalize(p - o.unsqueeze(1), dim=-1)  # (2, 1, 3) rays through it
        >>> [round(v, 4) for v in triangulate(o, d)[0].tolist()]
        [0.1, 0.2, -0.1]
    """
    check_shapes("triangulate", origins=(origins, "... K 3"), directions=(directions, "... K N 3"))
    eye = torch.eye(3, dtype=directions.dtype, device=directions.device)
    proj = eye - directions.unsqueeze(-1) * directions.unsqueeze(-2)  # (..., K, N, 3, 3): off each ray
    lhs = proj.sum(-4) + ridge * eye
    rhs = (proj @ origins.unsqueeze(-2).unsqueeze(-1).to(directions.dtype)).sum(-4)  # (..., N, 3, 1)
    return torch.linalg.solve(lhs, rhs).squeeze(-1)


def default_fov_for(distance: float, extent: float = 1.0, margin: float = 1.05) -> float:
    """Vertical field of view (degrees) at which a cube of side ``extent`` centred at the origin,
    seen from ``distance``, just fits the frame (with ``margin``). Useful for scene set-ups."""
    half = 0.5 * extent * math.sqrt(3) * margin
    return math.degrees(2 * math.asin(min(half / distance, 0.999)))
