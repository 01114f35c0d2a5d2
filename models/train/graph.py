"""Train the per-contact graph warm start (`deepcontact-graph`) on `deepcontact generate` data.

    deepcontact generate --seeds 0..110 --no-grids --out data3
    python models/train/graph.py --data data3 --loss mse --out models/graph-mse
    python models/train/graph.py --data data3 --loss unrolled --sweeps 10 --out models/graph

The model reads what builtin knows and predicts the correction (residual learning): per contact
the carried impulse, whether it was carried, normal, separation, relative velocity, restitution
bias, effective masses, the bodies' inverse masses and the normal's lever arms (15 features,
standardised with the training set's mean and deviation). An encoder (15 -> H) is followed by R
rounds of message passing over the contact-body graph: each contact sends K scalar channels
and K impulse-like vectors (qn n + qt t, with the sign of the impulse on each body: + on B,
- on A) to its moving bodies, which sum them; each contact reads its two bodies' sums (the
vectors projected on its normal and tangent) and updates its state residually. A linear head
gives the correction (dn, dt) in units of the impulse scale; the start is
`max(0, carried_n + dn), carried_t + dt`.

Losses: `mse` — the start against the step's final impulse; `unrolled` — the same distance after
`--sweeps` projected Gauss-Seidel sweeps run from the start on the recorded problem (the
solver's own rows, format 3): the sweeps remove the error PGS removes quickly, so what is left
to learn is the part that costs iterations. Sweeps here go colour by colour (contacts of one
colour share no moving body, so updating them together is exactly Gauss-Seidel in some order).

Seeds: train 0-99, validation 100-109 (early stopping on it; best epoch exported). Output:
`<out>.safetensors` (weights + architecture and feature statistics in the metadata) and the card
`<out>.json`, which also holds a check case: one validation step's inputs and the corrections
PyTorch computes for them, which the Rust forward pass must reproduce (`cargo test -p
deepcontact-graph`). `--check-only` rewrites only that case for an existing model.

ONNX: `--check-only --onnx [PATH]` loads the existing model and writes only an ONNX export of it
(default `<out>.onnx`; the weights and the card are left alone); `--onnx` after training writes
it too. The export (`export_onnx`, opset 17, one file) computes the same correction with dense
incidence matrices instead of `index_add`: inputs `features` [C, 15] (raw, standardised inside),
`incidence_a`, `incidence_b` [B, C] (1 where contact c's body A / B is body b and that body
moves, else 0), output `corrections` [C, 2] (N·s); C and B are dynamic. Before writing, the
wrapper is checked against `ContactGraph.correction` on validation steps (max difference 1e-5).

    python models/train/graph.py --data data3 --check-only --onnx --out models/graph
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch
from safetensors import safe_open
from safetensors.torch import save_file
from torch import nn

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dataset import seed_file  # noqa: E402
from train import seeds  # noqa: E402

FEATURES = [
    "carried_normal",
    "carried_tangent",
    "carried",
    "normal_x",
    "normal_y",
    "separation",
    "relative_velocity_normal",
    "relative_velocity_tangent",
    "velocity_bias",
    "normal_mass",
    "tangent_mass",
    "inverse_mass_a",
    "inverse_mass_b",
    "lever_normal_a",
    "lever_normal_b",
]


def load_steps(data_dir: Path, seed_list, every: int = 1, min_step: int = 0) -> list[dict]:
    """One dict of numpy arrays per recorded step (format 3 files)."""
    out = []
    for seed in seed_list:
        path = seed_file(data_dir, seed)
        with safe_open(str(path), framework="numpy") as f:
            meta = f.metadata() or {}
            if meta.get("format_version") != "3":
                raise ValueError(f"{path}: format {meta.get('format_version')}, need 3 (solver rows)")
            t = {k: f.get_tensor(k) for k in f.keys() if k not in ("inputs", "labels")}
        inverse = t["body_inverse_mass"].astype(np.float64)
        nb = inverse.shape[0]
        offsets = t["contact_offsets"]
        for s, step in enumerate(t["steps"]):
            if step < min_step or s % every:
                continue
            c = slice(int(offsets[s]), int(offsets[s + 1]))
            bodies = t["contact_solver_bodies"][c].astype(np.int64)
            n = t["contact_solver_normal"][c].astype(np.float64)
            anchors = t["contact_anchors"][c].astype(np.float64)
            ra, rb = anchors[:, :2], anchors[:, 2:]
            lever_a = ra[:, 0] * n[:, 1] - ra[:, 1] * n[:, 0]
            lever_b = rb[:, 0] * n[:, 1] - rb[:, 1] * n[:, 0]
            mass = t["contact_row_mass"][c].astype(np.float64)
            carried = t["contact_warm_start"][c].astype(np.float64)
            x = np.column_stack(
                [
                    carried[:, 0],
                    carried[:, 1],
                    t["contact_persisted"][c].astype(np.float64),
                    n[:, 0],
                    n[:, 1],
                    t["contact_separation"][c],
                    t["contact_relative_velocity"][c][:, 0],
                    t["contact_relative_velocity"][c][:, 1],
                    t["contact_velocity_bias"][c],
                    mass[:, 0],
                    mass[:, 1],
                    inverse[bodies[:, 0], 0],
                    inverse[bodies[:, 1], 0],
                    lever_a,
                    lever_b,
                ]
            )
            moving = inverse[:, 0] > 0
            out.append(
                {
                    "x": x,
                    "bodies": bodies,
                    "moving": moving[bodies].astype(np.float64),
                    "normal": n,
                    "anchors": anchors,
                    "mass": mass,
                    "friction": t["contact_friction"][c].astype(np.float64),
                    "bias": t["contact_velocity_bias"][c].astype(np.float64),
                    "carried": carried,
                    "label": t["contact_impulse"][c].astype(np.float64),
                    "inverse": inverse,
                    "velocity": np.column_stack(
                        [t["body_velocity"][s], t["body_angular_velocity"][s]]
                    ).astype(np.float64),
                    "colour": colours(bodies, moving),
                    "nb": nb,
                }
            )
    return out


def colours(bodies: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Greedy colouring of the contacts: two contacts sharing a moving body differ."""
    used: dict[int, set] = {}
    colour = np.zeros(len(bodies), dtype=np.int64)
    for k, (a, b) in enumerate(bodies):
        taken = set()
        for body in (a, b):
            if moving[body]:
                taken |= used.setdefault(int(body), set())
        c = 0
        while c in taken:
            c += 1
        colour[k] = c
        for body in (a, b):
            if moving[body]:
                used[int(body)].add(c)
    return colour


def batch(steps: list[dict], device="cpu") -> dict:
    """The disjoint union of some steps' graphs, as torch tensors."""
    cat = lambda k: np.concatenate([s[k] for s in steps])  # noqa: E731
    offsets = np.cumsum([0] + [s["nb"] for s in steps])
    bodies = np.concatenate([s["bodies"] + o for s, o in zip(steps, offsets)])
    colour = cat("colour")
    tt = lambda a, dt=torch.float32: torch.as_tensor(a, dtype=dt, device=device)  # noqa: E731
    return {
        "x": tt(cat("x")),
        "a": tt(bodies[:, 0], torch.int64),
        "b": tt(bodies[:, 1], torch.int64),
        "moving": tt(cat("moving")),
        "normal": tt(cat("normal")),
        "anchors": tt(cat("anchors")),
        "mass": tt(cat("mass")),
        "friction": tt(cat("friction")),
        "bias": tt(cat("bias")),
        "carried": tt(cat("carried")),
        "label": tt(cat("label")),
        "inverse": tt(cat("inverse")),
        "velocity": tt(cat("velocity")),
        "colours": [tt(np.nonzero(colour == c)[0], torch.int64) for c in range(colour.max() + 1)],
        "bodies": int(offsets[-1]),
    }


class ContactGraph(nn.Module):
    """The model described in the module docstring (mirrored by warmstart/graph/src/model.rs)."""

    def __init__(self, features: int, hidden: int, channels: int, rounds: int):
        super().__init__()
        self.k = channels
        self.encoder = nn.Linear(features, hidden)
        self.message = nn.ModuleList(nn.Linear(hidden, 3 * channels) for _ in range(rounds))
        self.update = nn.ModuleList(nn.Linear(hidden + 6 * channels, hidden) for _ in range(rounds))
        self.head = nn.Linear(hidden, 2)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)

    def forward(self, g: dict, mean: torch.Tensor, std: torch.Tensor, scale: float):
        """The start: `max(0, carried_n + dn), carried_t + dt`."""
        d = self.correction(g, mean, std, scale)
        c = g["carried"]
        return torch.stack([torch.relu(c[:, 0] + d[:, 0]), c[:, 1] + d[:, 1]], dim=1)

    def correction(self, g: dict, mean: torch.Tensor, std: torch.Tensor, scale: float):
        """The predicted correction `(dn, dt)` in N·s, [C, 2]."""
        x = (g["x"] - mean) / std
        n = g["normal"]
        t = torch.stack([-n[:, 1], n[:, 0]], dim=1)
        ma, mb = g["moving"][:, :1], g["moving"][:, 1:]
        a, b, k = g["a"], g["b"], self.k
        h = torch.relu(self.encoder(x))
        for message, update in zip(self.message, self.update):
            m = message(h)
            s, qn, qt = m[:, :k], m[:, k : 2 * k], m[:, 2 * k :]
            # Impulse-like vectors, K per contact, [C, K, 2]: + on B, - on A.
            v = qn[:, :, None] * n[:, None, :] + qt[:, :, None] * t[:, None, :]
            zs = torch.zeros(g["bodies"], k)
            zv = torch.zeros(g["bodies"], k, 2)
            sums = zs.index_add(0, a, s * ma).index_add(0, b, s * mb)
            vecs = zv.index_add(0, a, -v * ma[:, :, None]).index_add(0, b, v * mb[:, :, None])
            va, vb = vecs[a] * ma[:, :, None], vecs[b] * mb[:, :, None]
            read = torch.cat(
                [
                    sums[a] * ma,
                    sums[b] * mb,
                    (va * n[:, None, :]).sum(2),
                    (va * t[:, None, :]).sum(2),
                    (vb * n[:, None, :]).sum(2),
                    (vb * t[:, None, :]).sum(2),
                ],
                dim=1,
            )
            h = h + torch.relu(update(torch.cat([h, read], dim=1)))
        return self.head(h) * scale


class DenseContactGraph(nn.Module):
    """`ContactGraph.correction` with dense incidence matrices instead of `index_add` (for ONNX):
    a body's sums over its contacts are `incidence @ x`, a contact reads its body's sums back
    with `incidence.T @ sums`. Static bodies have zero rows, so they neither send nor receive."""

    def __init__(self, model: ContactGraph, mean, std, scale: float):
        super().__init__()
        self.model = model
        self.register_buffer("mean", torch.as_tensor(mean, dtype=torch.float32).clone())
        self.register_buffer("std", torch.as_tensor(std, dtype=torch.float32).clone())
        self.scale = float(scale)

    def forward(self, features, incidence_a, incidence_b):
        """Corrections `(dn, dt)` in N·s, [C, 2], from raw features [C, 15] and the
        incidence matrices [B, C]."""
        model, k = self.model, self.model.k
        x = (features - self.mean) / self.std
        nx, ny = features[:, 3:4], features[:, 4:5]
        # Tangent t = (-ny, nx).
        ta, tb = incidence_a.t(), incidence_b.t()
        h = torch.relu(model.encoder(x))
        for message, update in zip(model.message, model.update):
            m = message(h)
            s, qn, qt = m[:, :k], m[:, k : 2 * k], m[:, 2 * k :]
            # Impulse-like vectors qn n + qt t, [C, K] per component: + on B, - on A.
            vx = qn * nx - qt * ny
            vy = qn * ny + qt * nx
            sums = incidence_a @ s + incidence_b @ s
            sx = incidence_b @ vx - incidence_a @ vx
            sy = incidence_b @ vy - incidence_a @ vy
            ax, ay = ta @ sx, ta @ sy
            bx, by = tb @ sx, tb @ sy
            read = torch.cat(
                [
                    ta @ sums,
                    tb @ sums,
                    ax * nx + ay * ny,
                    -ax * ny + ay * nx,
                    bx * nx + by * ny,
                    -bx * ny + by * nx,
                ],
                dim=1,
            )
            h = h + torch.relu(update(torch.cat([h, read], dim=1)))
        return model.head(h) * self.scale


def incidences(bodies: np.ndarray, moving: np.ndarray, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """The [B, C] incidence matrices of `DenseContactGraph` for contacts `bodies` [C, 2] and
    per-contact moving flags `moving` [C, 2] (as `load_steps` writes them)."""
    c = np.arange(len(bodies))
    out = []
    for side in (0, 1):
        m = np.zeros((nb, len(bodies)), dtype=np.float32)
        m[bodies[:, side], c] = moving[:, side] > 0
        out.append(m)
    return out[0], out[1]


def export_onnx(model: ContactGraph, mean, std, scale: float, path: Path) -> DenseContactGraph:
    """Writes `DenseContactGraph(model, ...)` to `path` as ONNX (opset 17, one file, C and B
    dynamic) and returns the wrapper. Runs `onnx.checker` if `onnx` is importable."""
    wrapper = DenseContactGraph(model, mean, std, scale).eval()
    # Distinct, non-trivial sizes so that neither exporter specialises C or B.
    gen = torch.Generator().manual_seed(0)
    contacts, bodies = 7, 5
    features = torch.randn(contacts, len(FEATURES), generator=gen)
    ends = torch.randint(0, bodies, (contacts, 2), generator=gen)
    ia = torch.zeros(bodies, contacts)
    ib = torch.zeros(bodies, contacts)
    ia[ends[:, 0], torch.arange(contacts)] = 1.0
    ib[ends[:, 1], torch.arange(contacts)] = 1.0
    example = (features, ia, ib)
    names = dict(input_names=["features", "incidence_a", "incidence_b"], output_names=["corrections"])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.onnx")
    exporter = "dynamo"
    try:
        c, b = torch.export.Dim("contacts"), torch.export.Dim("bodies")
        torch.onnx.export(
            wrapper, example, str(tmp), opset_version=17, dynamo=True, external_data=False,
            dynamic_shapes=({0: c}, {0: b, 1: c}, {0: b, 1: c}), **names,
        )
    except Exception as e:  # older torch / exporter quirks: fall back to the TorchScript exporter
        print(f"dynamo export failed ({e}); using the TorchScript exporter", flush=True)
        exporter = "torchscript"
        torch.onnx.export(
            wrapper, example, str(tmp), opset_version=17, dynamo=False, do_constant_folding=True,
            dynamic_axes={"features": {0: "contacts"}, "incidence_a": {0: "bodies", 1: "contacts"},
                          "incidence_b": {0: "bodies", 1: "contacts"}, "corrections": {0: "contacts"}},
            **names,
        )
    try:
        import onnx
    except ImportError:
        tmp.replace(path)
        print(f"wrote {path} ({exporter} exporter; onnx not importable, not checked)")
        return wrapper
    proto = onnx.load(str(tmp), load_external_data=True)
    onnx.checker.check_model(proto, full_check=True)
    onnx.save(proto, str(path), save_as_external_data=False)
    tmp.unlink(missing_ok=True)
    for extra in list(path.parent.glob(tmp.name + ".data")) + list(path.parent.glob(path.name + ".data")):
        extra.unlink()
    opset = next((o.version for o in proto.opset_import if o.domain in ("", "ai.onnx")), None)
    print(f"wrote {path} ({path.stat().st_size} bytes, {exporter} exporter, opset {opset}); onnx.checker passed")
    return wrapper


def check_dense(wrapper: DenseContactGraph, model: ContactGraph, mean, std, scale, args, tolerance=1e-5) -> float:
    """Largest |wrapper - model.correction| (N·s) over every 5th validation step; raises if
    above `tolerance`."""
    worst, worst_size, steps = 0.0, 0.0, 0
    with torch.no_grad():
        for step in load_steps(args.data, seeds(args.validation_seeds), 5, 0):
            g = batch([step])
            expected = model.correction(g, torch.tensor(mean), torch.tensor(std), scale)
            ia, ib = incidences(step["bodies"], step["moving"], step["nb"])
            got = wrapper(g["x"], torch.from_numpy(ia), torch.from_numpy(ib))
            worst = max(worst, (got - expected).abs().max().item())
            worst_size = max(worst_size, expected.abs().max().item())
            steps += 1
    print(f"dense wrapper vs ContactGraph.correction on {steps} validation steps: max |difference| "
          f"{worst:.3g} N·s (largest correction {worst_size:.3g} N·s)")
    if not worst <= tolerance:
        raise ValueError(f"dense wrapper differs from the model by {worst} > {tolerance}")
    return worst


def pgs_sweeps(g: dict, start: torch.Tensor, sweeps: int) -> torch.Tensor:
    """`sweeps` projected Gauss-Seidel sweeps from `start` on the recorded rows (friction row,
    then normal row, per point; colour by colour), differentiable in `start`."""
    n = g["normal"]
    t = torch.stack([-n[:, 1], n[:, 0]], dim=1)
    ra, rb = g["anchors"][:, :2], g["anchors"][:, 2:]
    cross = lambda r, d: r[:, 0] * d[:, 1] - r[:, 1] * d[:, 0]  # noqa: E731
    a, b = g["a"], g["b"]
    ima, iia = g["inverse"][a, 0], g["inverse"][a, 1]
    imb, iib = g["inverse"][b, 0], g["inverse"][b, 1]
    mu, bias = g["friction"], g["bias"]
    ln = torch.relu(start[:, 0])
    lt = torch.maximum(torch.minimum(start[:, 1], mu * ln), -mu * ln)

    def apply(vel, idx, d, direction):
        """Velocity change of impulse `d` along `direction` at points `idx`."""
        p = d[:, None] * direction[idx]
        va = torch.cat([-ima[idx, None] * p, (-iia[idx] * cross(ra[idx], p))[:, None]], 1)
        vb = torch.cat([imb[idx, None] * p, (iib[idx] * cross(rb[idx], p))[:, None]], 1)
        return vel.index_add(0, a[idx], va).index_add(0, b[idx], vb)

    def rel(vel, idx, direction):
        """Relative velocity of B against A at points `idx` along `direction`."""
        x, y = a[idx], b[idx]
        wa, wb = vel[x, 2:3], vel[y, 2:3]
        pa = vel[x, :2] + wa * torch.stack([-ra[idx, 1], ra[idx, 0]], 1)
        pb = vel[y, :2] + wb * torch.stack([-rb[idx, 1], rb[idx, 0]], 1)
        return ((pb - pa) * direction[idx]).sum(1)

    everything = torch.arange(len(ln))
    vel = apply(g["velocity"], everything, ln, n)
    vel = apply(vel, everything, lt, t)
    for _ in range(sweeps):
        for idx in g["colours"]:
            new_t = lt[idx] - g["mass"][idx, 1] * rel(vel, idx, t)
            bound = mu[idx] * ln[idx]
            new_t = torch.maximum(torch.minimum(new_t, bound), -bound)
            vel = apply(vel, idx, new_t - lt[idx], t)
            lt = lt.index_copy(0, idx, new_t)
            new_n = torch.relu(ln[idx] - g["mass"][idx, 0] * (rel(vel, idx, n) - bias[idx]))
            vel = apply(vel, idx, new_n - ln[idx], n)
            ln = ln.index_copy(0, idx, new_n)
    return torch.stack([ln, lt], dim=1)


def sweep_check(args) -> None:
    """Prints the mean squared distance (N·s²) from the recorded warm start to the final impulses
    after k sweeps of `pgs_sweeps`: it must fall towards 0 if the sweeps are the solver's."""
    steps = load_steps(args.data, seeds(args.validation_seeds), 5, 150)
    g = batch(steps)
    with torch.no_grad():
        for k in (0, 10, 100, 400):
            d = ((pgs_sweeps(g, g["carried"], k) - g["label"]) ** 2).mean().item()
            print(f"{k} sweeps: {d:.4g}")
    print(f"({len(steps)} steps; mean squared final impulse {(g['label'] ** 2).mean().item():.4g})")


def loss_of(model, g, stats, args) -> torch.Tensor:
    mean, std, scale = stats
    start = model(g, mean, std, scale)
    if args.loss == "unrolled":
        start = pgs_sweeps(g, start, args.sweeps)
    return (((start - g["label"]) / scale) ** 2).mean()


def evaluate(model, batches, stats, args) -> float:
    with torch.no_grad():
        total = sum(loss_of(model, g, stats, args).item() * len(g["x"]) for g in batches)
        return total / sum(len(g["x"]) for g in batches)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True, help="output path without extension")
    p.add_argument("--loss", choices=["mse", "unrolled"], default="unrolled")
    p.add_argument("--sweeps", type=int, default=10, help="unrolled sweeps (default 10)")
    p.add_argument("--train-seeds", default="0..100")
    p.add_argument("--validation-seeds", default="100..110")
    p.add_argument("--every", type=int, default=2, help="keep every n-th training step")
    p.add_argument("--min-step", type=int, default=0)
    p.add_argument("--hidden", type=int, default=16)
    p.add_argument("--channels", type=int, default=4)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--batch", type=int, default=32, help="steps per batch")
    p.add_argument("--lr", type=float, default=2e-3)
    p.add_argument("--minutes", type=float, default=15.0, help="training time limit")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--check-only", action="store_true", help="only (re)write the card's check case")
    p.add_argument("--onnx", nargs="?", const=True, default=None, metavar="PATH",
                   help="also write an ONNX export (default <out>.onnx); with --check-only, only that")
    p.add_argument("--sweep-check", action="store_true",
                   help="only check the PyTorch sweeps against the solver: distance from builtin's "
                   "start to the final impulses after 0, 10, 100, 400 sweeps (validation steps >= 150)")
    args = p.parse_args()
    if args.sweep_check:
        sweep_check(args)
        return
    if args.check_only:
        model, mean, std, scale = load_model(args.out.with_suffix(".safetensors"))
        if args.onnx:
            write_onnx(model, args, mean, std, scale)
        else:
            write_check(model, args, mean, std, scale)
        return
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)

    train = load_steps(args.data, seeds(args.train_seeds), args.every, args.min_step)
    valid = load_steps(args.data, seeds(args.validation_seeds), 5, args.min_step)
    x = np.concatenate([s["x"] for s in train])
    mean, std = x.mean(0), np.maximum(x.std(0), 1e-6)
    scale = float(np.sqrt((np.concatenate([s["label"] for s in train]) ** 2).mean()))
    stats = (torch.tensor(mean, dtype=torch.float32), torch.tensor(std, dtype=torch.float32), scale)
    print(f"{len(train)} training steps, {len(valid)} validation steps, impulse scale {scale:.4g}")
    vbatches = [batch(valid[i : i + 64]) for i in range(0, len(valid), 64)]

    model = ContactGraph(len(FEATURES), args.hidden, args.channels, args.rounds)
    opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    carried_only = evaluate(model, vbatches, stats, args)
    print(f"validation loss of the carried impulses (zero correction): {carried_only:.5f}")
    best, best_state, best_epoch, history = carried_only, copy.deepcopy(model.state_dict()), 0, []
    began = time.time()
    for epoch in range(1, args.epochs + 1):
        order = rng.permutation(len(train))
        total, count = 0.0, 0
        for i in range(0, len(order), args.batch):
            g = batch([train[j] for j in order[i : i + args.batch]])
            loss = loss_of(model, g, stats, args)
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()
            total, count = total + loss.item() * len(g["x"]), count + len(g["x"])
            if time.time() - began > 60 * args.minutes:
                break
        v = evaluate(model, vbatches, stats, args)
        history.append({"epoch": epoch, "train": total / count, "validation": v})
        print(f"epoch {epoch}: train {total / count:.5f} validation {v:.5f} ({time.time() - began:.0f} s)")
        if v < best:
            best, best_state, best_epoch = v, copy.deepcopy(model.state_dict()), epoch
        if time.time() - began > 60 * args.minutes:
            break
    model.load_state_dict(best_state)
    export(model, args, mean, std, scale, best, carried_only, best_epoch, history, len(train), time.time() - began)
    if args.onnx:
        write_onnx(model, args, mean, std, scale)


def write_onnx(model, args, mean, std, scale):
    """The ONNX export at `--onnx PATH` (default `<out>.onnx`), after checking the dense
    wrapper against the model on validation steps."""
    model.eval()
    path = args.out.with_suffix(".onnx") if args.onnx is True else Path(args.onnx)
    check_dense(DenseContactGraph(model, mean, std, scale).eval(), model, mean, std, scale, args)
    export_onnx(model, mean, std, scale, path)


def export(model, args, mean, std, scale, best, carried_only, best_epoch, history, n_train, seconds):
    """Weights + architecture to `<out>.safetensors`, the card to `<out>.json`."""
    args.out.parent.mkdir(parents=True, exist_ok=True)
    weights = {k: v.detach().contiguous().float() for k, v in model.state_dict().items()}
    weights["feature_mean"] = torch.tensor(mean, dtype=torch.float32)
    weights["feature_std"] = torch.tensor(std, dtype=torch.float32)
    arch = {
        "model": "contact-graph",
        "features": FEATURES,
        "hidden": args.hidden,
        "channels": args.channels,
        "rounds": args.rounds,
        "impulse_scale": scale,
    }
    path = args.out.with_suffix(".safetensors")
    save_file(weights, str(path), metadata={"format": "deepcontact-graph-model", "format_version": "1", "architecture": json.dumps(arch)})
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    card = {
        "format": "deepcontact-graph-card",
        "format_version": "1",
        "name": args.out.name,
        "file": path.name,
        "sha256": digest,
        "architecture": arch,
        "parameters": sum(p.numel() for p in model.parameters()),
        "loss": args.loss if args.loss == "mse" else f"unrolled, {args.sweeps} PGS sweeps",
        "target": "the step's final impulses (builtin start, PGS, thesis stop rule)",
        "train_seeds": args.train_seeds,
        "train_steps": n_train,
        "every": args.every,
        "validation_seeds": args.validation_seeds,
        "validation_loss": best,
        "validation_loss_of_carried": carried_only,
        "best_epoch": best_epoch,
        "history": history,
        "training_seconds": round(seconds),
        "trained_on": f"{platform.processor() or platform.machine()}, {args.threads} threads, torch {torch.__version__}",
        "hyperparameters": {k: getattr(args, k) for k in ("batch", "lr", "minutes", "epochs", "seed", "min_step")},
    }
    args.out.with_suffix(".json").write_text(json.dumps(card, indent=2) + "\n")
    write_check(model, args, mean, std, scale)
    print(f"wrote {path} ({path.stat().st_size} bytes) and its card; best validation {best:.5f} at epoch {best_epoch}")


def load_model(path: Path):
    """A model written by `export`, with its feature statistics and impulse scale."""
    with safe_open(str(path), framework="pt") as f:
        arch = json.loads(f.metadata()["architecture"])
        state = {k: f.get_tensor(k) for k in f.keys()}
    model = ContactGraph(len(FEATURES), arch["hidden"], arch["channels"], arch["rounds"])
    mean, std = state.pop("feature_mean").numpy(), state.pop("feature_std").numpy()
    model.load_state_dict(state)
    return model, mean, std, arch["impulse_scale"]


def write_check(model, args, mean, std, scale, contacts=(20, 80)):
    """Adds to the card the first validation step with `contacts` points that touches a
    static body: its raw features, bodies (renumbered from 0), which bodies move, and the
    corrections (dn, dt) in N·s that PyTorch computes (float32)."""
    for step in load_steps(args.data, seeds(args.validation_seeds), 1, 0):
        if contacts[0] <= len(step["x"]) <= contacts[1] and step["moving"].min() == 0:
            break
    else:
        raise ValueError("no validation step fits the check case")
    used, local = np.unique(step["bodies"], return_inverse=True)
    local = local.reshape(-1, 2)
    g = batch([{**step, "bodies": local, "nb": len(used)}])
    with torch.no_grad():
        f32 = lambda a: torch.tensor(a, dtype=torch.float32)  # noqa: E731
        corrections = model.correction(g, f32(mean), f32(std), scale)
    moving = np.zeros(len(used), dtype=bool)
    moving[local[:, 0]] = step["moving"][:, 0] > 0
    moving[local[:, 1]] = step["moving"][:, 1] > 0
    path = args.out.with_suffix(".json")
    card = json.loads(path.read_text())
    card["check"] = {
        "features": step["x"].astype(np.float32).tolist(),
        "bodies": local.tolist(),
        "moving": moving.tolist(),
        "corrections": corrections.numpy().tolist(),
    }
    path.write_text(json.dumps(card, indent=2) + "\n")


if __name__ == "__main__":
    main()
