"""How hard each loss term pulls: its value and the norm of its gradient on the network's parameters (weight 1),
beside the `cpu` objective's own, for a freshly initialised `cpu` network and the shipped `human` model, on one
batch of 8 quadruplets of a dataset (issue 30: the weights of experiments/ablation/limbs.txt come from these ratios).

    python experiments/limbs/term_gradients.py DATA [TERM ...]     # e.g. a tiny human set, all terms by default

DATA: a quadruplet dataset at 64 px (`cerberus data generate --dataset human --size tiny --out DATA`).
"""
from __future__ import annotations

import sys
from dataclasses import replace

import torch

from cerberus_core.datasets.dataset import Dataset

TERMS_SHOWN = ["coverage", "keypoint_coverage", "overlap", "rotation", "chamfer", "hidden", "silhouette", "recon"]


def main(argv: list[str]) -> int:
    from cerberus_core import make_renderer
    from cerberus_core.model import Cerberus
    from cerberus_core.run import Run
    from cerberus_core.train.data import quadruplet_batch
    from cerberus_core.train.objective import TERMS, quadruplet_objective
    from cerberus_core.train.settings import load_config

    if not argv:
        print(__doc__)
        return 2
    torch.set_num_threads(1)
    data = Dataset.open(argv[0]).quadruplets()
    scene = data.scene
    cfg = load_config(preset="cpu")
    cfg.model.depth_offset = scene.distance
    raw = torch.utils.data.default_collate([data[i % len(data)] for i in range(8)])
    batch = quadruplet_batch(raw, torch.device("cpu"), scene, 64)
    renderer = make_renderer("warp")
    torch.manual_seed(0)
    for label, model in (("init", Cerberus(cfg.model)), ("shipped human", Run.load("human").model)):
        model.train()

        def pull(losses, model=model):
            out = quadruplet_objective(model, renderer, batch, scene, losses, torch.Generator().manual_seed(0),
                                       antialias=cfg.render.antialias, step=10_000)
            model.zero_grad(set_to_none=True)
            if not out.total.requires_grad:  # a term that is 0 with no gradient (no hidden part)
                return out, 0.0
            out.total.backward()
            grads = [p.grad.float().square().sum() for p in model.parameters() if p.grad is not None]
            return out, float(torch.stack(grads).sum().sqrt())

        out, whole = pull(cfg.losses)
        print(f"{label}: cpu objective {out.terms['total'].item():.4f}, gradient norm {whole:.4g}")
        for name in argv[1:] or TERMS_SHOWN:
            o, g = pull(replace(cfg.losses, **({t: 0.0 for t in TERMS} | {name: 1.0})))
            print(f"  {name:18s} value {o.terms[name].item():.4g}  gradient norm {g:.4g}  "
                  f"{g / whole:.3g} of the cpu objective's")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
