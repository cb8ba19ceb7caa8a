#!/usr/bin/env python3
"""Checks a model written by `policy-codegen export-onnx`: the ONNX checker accepts it, and
onnxruntime on the reference inputs beside it (`reference.json`) gives the outputs of the
checkpoint's f32 forward pass, within 1e-5 of each output's largest magnitude, as one
batch and row by row.

Run: python3 policy-codegen/tools/check_onnx.py <export dir>   (pip install onnx onnxruntime numpy)
"""
import json
import pathlib
import sys

import numpy as np
import onnx
import onnxruntime as ort

TOLERANCE = 1e-5


def main():
    out_dir = pathlib.Path(sys.argv[1])
    model_path = out_dir / "policy.onnx"
    onnx.checker.check_model(onnx.load(model_path), full_check=True)
    ref = json.loads((out_dir / "reference.json").read_text())
    session = ort.InferenceSession(str(model_path), providers=["CPUExecutionProvider"])
    inputs = {i.name for i in session.get_inputs()}
    if inputs != set(ref["inputs"]):
        raise SystemExit(f"model inputs {sorted(inputs)} differ from the reference's {sorted(ref['inputs'])}")
    outputs = [o.name for o in session.get_outputs()]
    if set(outputs) != set(ref["outputs"]):
        raise SystemExit(f"model outputs {outputs} differ from the reference's {sorted(ref['outputs'])}")
    feeds = {k: np.array(v, dtype=np.float32) for k, v in ref["inputs"].items()}
    rows = len(next(iter(feeds.values())))
    batch = dict(zip(outputs, session.run(None, feeds)))
    single = [dict(zip(outputs, session.run(None, {k: v[i : i + 1] for k, v in feeds.items()}))) for i in range(rows)]
    failed = False
    for name in outputs:
        expected = np.array(ref["outputs"][name], dtype=np.float32)
        scale = max(float(np.abs(expected).max()), 1e-12)
        got_single = np.concatenate([s[name] for s in single])
        for how, got in (("batch", batch[name]), ("row by row", got_single)):
            if got.shape != expected.shape:
                raise SystemExit(f"{name} ({how}): shape {got.shape}, expected {expected.shape}")
            rel = float(np.abs(got.astype(np.float64) - expected).max()) / scale
            ok = rel <= TOLERANCE
            failed |= not ok
            print(f"{name} {expected.shape} ({how}): max |onnxruntime - f32| / max |f32| = {rel:.2e} "
                  f"(max |f32| {scale:.3g}) {'ok' if ok else 'FAILS'} {TOLERANCE:g}")
    print(f"onnxruntime {ort.__version__}, onnx {onnx.__version__}: {model_path} ({ref['checkpoint']}, {rows} inputs)")
    if failed:
        raise SystemExit(f"onnxruntime differs from the f32 forward pass by more than {TOLERANCE:g} relative")


if __name__ == "__main__":
    main()
