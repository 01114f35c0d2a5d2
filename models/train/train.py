"""Train a Pressure or Peak CNN on `deepcontact generate` data and export it to ONNX + model card.

    python models/train/train.py --model pressure --data data --out models
    python models/train/train.py --model pressure --residual --data data --out models

With --residual (Pressure only) the model also reads the carried impulses as two input grids
(`carried`, format 3) and learns the correction `labels - carried`; the provider adds the
correction read back at each contact to that contact's exact carried impulse.

Loss: MSE on contact-bearing nodes (masked), in units of the per-channel label RMS; L2 1e-2 on
conv / dense weights (Adam's weight_decay); Adam 1e-3; batch 40; validation on seeds 100-109
after every epoch, early stopping on it (the best epoch's weights are exported).
Export: BatchNorm folded into the convolutions, torch.onnx.export (opset 17, batch 1, one file,
no external data), then checked against PyTorch with ONNX Runtime when it is installed.
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
from torch import nn

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dataset import load_seeds  # noqa: E402
from models import MODELS, parameter_count  # noqa: E402


def seeds(text: str) -> list[int]:
    """The seeds grammar of deepcontact (`deepcontact_experiments::seeds`): comma-separated
    `a`, `a..b` (end exclusive) or `a..=b`; order kept; empty ranges and repeats are errors."""
    out: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        if "..=" in part:
            a, b = part.split("..=")
            rng = range(int(a), int(b) + 1)
        elif ".." in part:
            a, b = part.split("..")
            rng = range(int(a), int(b))
        else:
            rng = range(int(part), int(part) + 1)
        if len(rng) == 0:
            raise ValueError(f"seeds `{text}`: `{part}` is an empty range")
        out.extend(rng)
    if not out:
        raise ValueError(f"seeds `{text}`: no seed")
    if len(set(out)) != len(out):
        raise ValueError(f"seeds `{text}`: a seed is listed twice")
    return out


def rms_scale(values: np.ndarray, axis_channels: int = 1) -> np.ndarray:
    """1 / RMS of the non-zero interior entries, per channel."""
    inner = values[:, :, 1:-1, 1:-1]
    scales = []
    for c in range(values.shape[axis_channels]):
        v = inner[:, c]
        v = v[v != 0]
        rms = float(np.sqrt(np.mean(v.astype(np.float64) ** 2))) if v.size else 1.0
        scales.append(1.0 / rms if rms > 0 else 1.0)
    return np.asarray(scales, dtype=np.float32)


def masked_loss(pred, y, mask, out_scale):
    err = ((pred - y) / out_scale) ** 2 * mask
    return err.sum() / (mask.sum() * pred.shape[1]).clamp_min(1.0)


def evaluate(model, x, y, m, out_scale, batch=200):
    model.eval()
    total, count = 0.0, 0.0
    with torch.no_grad():
        for i in range(0, len(x), batch):
            xb, yb, mb = x[i : i + batch], y[i : i + batch], m[i : i + batch]
            err = ((model(xb) - yb) / out_scale) ** 2 * mb
            total += float(err.sum())
            count += float(mb.sum()) * yb.shape[1]
    return total / max(count, 1.0)


def fold_batchnorm(model: nn.Module) -> nn.Module:
    """Folds every Conv2d followed by BatchNorm2d inside an nn.Sequential (eval mode)."""
    model = copy.deepcopy(model).eval()
    for module in model.modules():
        if isinstance(module, nn.Sequential):
            layers = list(module)
            for i in range(len(layers) - 1):
                if isinstance(layers[i], nn.Conv2d) and isinstance(layers[i + 1], nn.BatchNorm2d):
                    module[i] = torch.nn.utils.fusion.fuse_conv_bn_eval(layers[i], layers[i + 1])
                    module[i + 1] = nn.Identity()
    return model


def export(model: nn.Module, path: Path, opset: int = 17) -> tuple[str, int]:
    import onnx

    model = fold_batchnorm(model)
    dummy = torch.zeros(1, model.in_scale.shape[1], 61, 61)
    tmp = path.with_suffix(".tmp.onnx")
    exporter = "dynamo"
    try:
        torch.onnx.export(model, (dummy,), str(tmp), input_names=["grids"], output_names=["impulses"],
                          opset_version=opset, dynamo=True, external_data=False)
    except Exception as e:  # older torch / exporter quirks: fall back to the TorchScript exporter
        print(f"dynamo export failed ({e}); using the TorchScript exporter", flush=True)
        exporter = "torchscript"
        torch.onnx.export(model, (dummy,), str(tmp), input_names=["grids"], output_names=["impulses"],
                          opset_version=opset, dynamo=False, do_constant_folding=True)
    proto = onnx.load(str(tmp), load_external_data=True)
    onnx.checker.check_model(proto)
    onnx.save(proto, str(path), save_as_external_data=False)
    tmp.unlink(missing_ok=True)
    for extra in path.parent.glob(path.name + ".data"):
        extra.unlink()
    for extra in path.parent.glob(tmp.name + ".data"):
        extra.unlink()
    version = next((o.version for o in proto.opset_import if o.domain in ("", "ai.onnx")), opset)
    return exporter, version


def check_with_onnxruntime(model: nn.Module, path: Path, x: torch.Tensor) -> float | None:
    try:
        import onnxruntime as ort
    except ImportError:
        return None
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    model.eval()
    worst = 0.0
    with torch.no_grad():
        for i in range(min(len(x), 8)):
            ref = model(x[i : i + 1]).numpy()
            got = sess.run(None, {"grids": x[i : i + 1].numpy()})[0]
            worst = max(worst, float(np.abs(ref - got).max() / max(np.abs(ref).max(), 1e-12)))
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", choices=sorted(MODELS), required=True)
    ap.add_argument("--data", type=Path, default=Path("data"))
    ap.add_argument("--out", type=Path, default=Path("models"))
    ap.add_argument("--train-seeds", default="0..100")
    ap.add_argument("--val-seeds", default="100..110")
    ap.add_argument("--every", type=int, default=5, help="keep every k-th recorded step")
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--patience", type=int, default=4)
    ap.add_argument("--batch", type=int, default=40)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--weight-decay", type=float, default=1e-2)
    ap.add_argument("--time-limit", type=float, default=3000.0, help="stop training after this many seconds")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--hardware", default="", help="text for the model card (default: CPU model)")
    ap.add_argument(
        "--residual",
        action="store_true",
        help="Pressure only: read the carried impulses as 2 more input channels and predict the "
        "correction to them (labels minus carried); exported as <model>-residual",
    )
    args = ap.parse_args()
    if args.residual and args.model != "pressure":
        ap.error("--residual is implemented for pressure only")
    name = f"{args.model}-residual" if args.residual else args.model

    torch.manual_seed(args.seed)
    np.random.seed(args.seed)
    if args.threads:
        torch.set_num_threads(args.threads)
    device = "cuda" if torch.cuda.is_available() else "cpu"

    t0 = time.time()
    train_seeds, val_seeds = seeds(args.train_seeds), seeds(args.val_seeds)
    x, y, m, header = load_seeds(args.data, train_seeds, every=args.every, carried=args.residual)
    xv, yv, mv, _ = load_seeds(args.data, val_seeds, every=args.every, carried=args.residual)
    if args.residual:
        # Target: the correction to the carried impulses (on the same grids).
        y, yv = y - x[:, 6:], yv - xv[:, 6:]
    print(f"data: train {x.shape} val {xv.shape} in {time.time() - t0:.1f}s", flush=True)

    model = MODELS[args.model](cin=8) if args.residual else MODELS[args.model]()
    model.in_scale.copy_(torch.from_numpy(rms_scale(x)).view(1, -1, 1, 1))
    out_rms = 1.0 / rms_scale(y)
    model.out_scale.copy_(torch.from_numpy(out_rms.astype(np.float32)).view(1, -1, 1, 1))
    model.to(device)
    out_scale = model.out_scale

    decay = [p for n, p in model.named_parameters() if p.ndim > 1]
    no_decay = [p for n, p in model.named_parameters() if p.ndim <= 1]
    opt = torch.optim.Adam(
        [{"params": decay, "weight_decay": args.weight_decay}, {"params": no_decay, "weight_decay": 0.0}], lr=args.lr
    )
    X, Y, M = (torch.from_numpy(a).to(device) for a in (x, y, m))
    XV, YV, MV = (torch.from_numpy(a).to(device) for a in (xv, yv, mv))

    best = (float("inf"), None, 0, float("nan"))
    history = []
    t_train = time.time()
    epochs_run = 0
    stopped = "epochs"
    for epoch in range(1, args.epochs + 1):
        model.train()
        perm = torch.randperm(len(X), device=device)
        total, batches = 0.0, 0
        for i in range(0, len(X), args.batch):
            idx = perm[i : i + args.batch]
            loss = masked_loss(model(X[idx]), Y[idx], M[idx], out_scale)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            total += float(loss)
            batches += 1
        train_loss = total / max(batches, 1)
        val_loss = evaluate(model, XV, YV, MV, out_scale)
        epochs_run = epoch
        history.append({"epoch": epoch, "train": train_loss, "val": val_loss, "seconds": time.time() - t_train})
        print(f"epoch {epoch:3d} train {train_loss:.5f} val {val_loss:.5f} ({time.time() - t_train:.0f}s)", flush=True)
        if val_loss < best[0]:
            best = (val_loss, copy.deepcopy(model.state_dict()), epoch, train_loss)
        elif epoch - best[2] >= args.patience:
            stopped = f"early stopping (no validation improvement for {args.patience} epochs)"
            break
        if time.time() - t_train > args.time_limit:
            stopped = f"time limit {args.time_limit:.0f}s"
            break
    wall = time.time() - t_train
    zero_val = float((((YV / out_scale) ** 2) * MV).sum() / (MV.sum() * YV.shape[1]))
    model.load_state_dict(best[1])
    model.to("cpu").eval()
    train_eval = evaluate(model, torch.from_numpy(x[:2000]), torch.from_numpy(y[:2000]), torch.from_numpy(m[:2000]),
                          model.out_scale)

    args.out.mkdir(parents=True, exist_ok=True)
    onnx_path = args.out / f"{name}.onnx"
    exporter, opset = export(model, onnx_path)
    ort_err = check_with_onnxruntime(model, onnx_path, torch.from_numpy(xv[:8]))
    print(f"exported {onnx_path} ({onnx_path.stat().st_size} bytes, {exporter}); onnxruntime rel. error {ort_err}")

    import onnx

    hardware = args.hardware or f"{platform.processor() or platform.machine()}, {torch.get_num_threads()} threads ({device})"
    card = {
        "format": "deepcontact-model-card",
        "format_version": 1,
        "name": name,
        "architecture": " ".join((MODELS[args.model].__doc__ or "").split()),
        "parameters": parameter_count(model),
        # Binds the card to this exact file: the Rust loader refuses another model with it.
        "model_sha256": hashlib.sha256(onnx_path.read_bytes()).hexdigest(),
        "grid_layout": header["grid_layout"],
        "input": {
            "name": "grids",
            "shape": [1, x.shape[1], 61, 61],
            "channels": header["input_channels"] + (["carried_normal", "carried_tangent"] if args.residual else []),
        },
        "residual": args.residual,
        "output": {"name": "impulses", "shape": [1, 2, 61, 61], "channels": header["output_channels"]},
        "training": {
            "data": {
                "scene": header["scene"], "bodies": int(header["bodies"]), "steps_simulated": int(header["steps_simulated"]),
                "warm_start": header["warm_start"], "solver": header["solver"], "dt": float(header["dt"]),
                "label_source": header["label_source"],
            },
            "train_seeds": args.train_seeds, "validation_seeds": args.val_seeds, "every_kth_step": args.every,
            "train_samples": int(len(x)), "validation_samples": int(len(xv)),
            "loss": "MSE on contact-bearing nodes, per output channel divided by the label RMS (out_scale)",
            "optimizer": f"Adam lr {args.lr}, L2 (weight decay) {args.weight_decay} on conv/dense weights, batch {args.batch}",
            "epochs": epochs_run, "best_epoch": best[2], "stopped_by": stopped,
            "final_train_loss": train_eval, "final_validation_loss": best[0],
            "zero_prediction_validation_loss": zero_val, "history": history,
            "wall_time_seconds": round(wall, 1), "hardware": hardware,
            "torch_version": torch.__version__, "onnx_version": onnx.__version__, "opset": opset,
            "exporter": exporter, "onnxruntime_max_rel_error_vs_torch": ort_err,
            "input_scale": model.in_scale.view(-1).tolist(), "output_scale": model.out_scale.view(-1).tolist(),
        },
    }
    (args.out / f"{name}.json").write_text(json.dumps(card, indent=2) + "\n")
    print(f"card {args.out / (name + '.json')}: val {best[0]:.5f} after {epochs_run} epochs, {wall:.0f}s")


if __name__ == "__main__":
    main()
