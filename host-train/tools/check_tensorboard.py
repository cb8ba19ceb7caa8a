#!/usr/bin/env python3
"""Reads a training run's TensorBoard event file with TensorBoard's own reader
(EventAccumulator: TFRecord framing with its CRCs, Event protobufs) and checks it against
the run's metrics.csv: in the newest event file every column is a scalar tag and every
cell a value at its iteration (as float32).

Run: python3 host-train/tools/check_tensorboard.py <run dir>   (pip install tensorboard)
"""
import csv
import pathlib
import sys

import numpy as np
from tensorboard.backend.event_processing import event_accumulator


def main():
    run_dir = pathlib.Path(sys.argv[1])
    # A run started again in the same directory adds a file, as rsl_rl's writer does; the
    # newest is the one metrics.csv was last written with.
    files = sorted(run_dir.glob("events.out.tfevents.*"), key=lambda f: f.stat().st_mtime)
    if not files:
        raise SystemExit(f"{run_dir}: no events.out.tfevents.* file")
    files = files[-1:]
    acc = event_accumulator.EventAccumulator(str(files[0]), size_guidance={event_accumulator.SCALARS: 0})
    acc.Reload()
    tags = set(acc.Tags()["scalars"])
    with open(run_dir / "metrics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    columns = [c for c in rows[0].keys() if c != "iteration"]
    missing = [c for c in columns if c not in tags]
    if missing:
        raise SystemExit(f"{files[0].name}: no scalars for {missing}")
    extra = sorted(tags - set(columns))
    if extra:
        raise SystemExit(f"{files[0].name}: scalars {extra} are not in metrics.csv")
    values = 0
    for tag in columns:
        events = {e.step: e.value for e in acc.Scalars(tag)}
        for row in rows:
            cell = row[tag]
            if cell == "":
                continue
            step = int(float(row["iteration"]))
            want = np.float32(float(cell))
            got = events.get(step)
            if got is None or not (np.float32(got) == want or (np.isnan(want) and np.isnan(got))):
                raise SystemExit(f"{tag} at step {step}: event file has {got}, metrics.csv {cell}")
            values += 1
    print(f"{files[0].name}: {len(columns)} scalar tags, {len(rows)} steps, {values} values match metrics.csv")


if __name__ == "__main__":
    main()
