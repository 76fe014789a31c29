#!/usr/bin/env python3
"""Markdown table comparing the forecaster's CPU timings: candle / ONNX Runtime
(`echoctl bench sizes --json`) against PyTorch (scripts/bench_pytorch.py).

    python3 scripts/bench_compare.py --candle .cache/bench/candle-*.json \
        --pytorch .cache/bench/pytorch-*.json

Every file: {"backend_note": str, "cases": [{"model", "batch", "kind", "backend",
"median_ms", "samples"}, ...]}. One row per (model, kind, batch); per backend the median of
the files' medians (one file per round), and the ratio of each non-PyTorch backend to
"pytorch" (explicit attention; > 1: slower than PyTorch). --candle may be left out: the
PyTorch medians alone. Standard library only.
"""

import argparse
import json
import statistics
import sys
from collections import defaultdict

MODEL_ORDER = ["d64", "d256"]
KIND_ORDER = ["inference", "train-step"]
BACKEND_ORDER = ["candle-cpu", "onnxruntime-cpu", "pytorch", "pytorch-sdpa"]
REFERENCE = "pytorch"


def order(value, known):
    return (known.index(value), "") if value in known else (len(known), str(value))


def load(paths):
    """(model, kind, batch) → backend → [median_ms per file]; the files' notes."""
    runs = defaultdict(lambda: defaultdict(list))
    notes = []
    for p in paths:
        try:
            with open(p) as f:
                doc = json.load(f)
            cases = doc["cases"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            sys.exit(f"{p}: not a benchmark file ({e})")
        note = doc.get("backend_note")
        if note and note not in notes:
            notes.append(note)
        for c in cases:
            try:
                key = (str(c["model"]), str(c["kind"]), int(c["batch"]))
                runs[key][str(c["backend"])].append(float(c["median_ms"]))
            except (KeyError, TypeError, ValueError) as e:
                sys.exit(f"{p}: bad case {c} ({e})")
    return runs, notes


def fmt_ms(v):
    if v is None:
        return "–"
    return f"{v:.3f}" if v < 10 else f"{v:.1f}" if v < 1000 else f"{v:.0f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--candle", nargs="*", default=[], help="echoctl bench sizes JSON files")
    ap.add_argument("--pytorch", nargs="+", required=True, help="bench_pytorch.py JSON files")
    args = ap.parse_args()

    runs, notes = load(args.candle + args.pytorch)
    if not runs:
        sys.exit("no cases in the files")
    backends = sorted({b for per in runs.values() for b in per},
                      key=lambda b: order(b, BACKEND_ORDER))
    others = [b for b in backends if not b.startswith("pytorch")]
    keys = sorted(runs, key=lambda k: (order(k[0], MODEL_ORDER), order(k[1], KIND_ORDER), k[2]))

    med = {k: {b: statistics.median(v) for b, v in runs[k].items()} for k in keys}
    header = ["model", "kind", "batch"] + [f"{b} ms" for b in backends]
    header += [f"{b} / {REFERENCE}" for b in others]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * 3 + "---:|" * (len(header) - 3))
    for k in keys:
        m = med[k]
        row = [k[0], k[1], str(k[2])] + [fmt_ms(m.get(b)) for b in backends]
        for b in others:
            ref = m.get(REFERENCE)
            row.append(f"{m[b] / ref:.2f}" if b in m and ref else "–")
        print("| " + " | ".join(row) + " |")

    print()
    counts = defaultdict(set)
    for per in runs.values():
        for b, v in per.items():
            counts[b].add(len(v))
    runs_note = ", ".join(
        f"{b} {'/'.join(map(str, sorted(counts[b])))}" for b in backends
    )
    print(f"Median over runs of each run's median (runs: {runs_note}); "
          f"{len(args.candle)} candle file(s), {len(args.pytorch)} PyTorch file(s).")
    for n in notes:
        print(f"- {n}")


if __name__ == "__main__":
    main()
