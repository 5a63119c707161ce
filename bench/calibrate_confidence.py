#!/usr/bin/python3
"""Calibrates the 2D recognition's confidence (docs/recognition.md, "Calibration").

usage: bench/calibrate_confidence.py CALIBRATION.csv [--l2 0.01] [--min-evidence 0.85]
                                     [--with-evidence]

CALIBRATION.csv: the labelled candidates of the recognition benchmark, one row per candidate
(every placement and every rejected search), written by
`bench/recognition_fields.sh calib BUILD WORK` (columns `field`, `label` and the placements
JSON's numeric keys flattened, e.g. `verification.seen`).

Fits P(true | terms) = σ(bias + Σ w_k · term_k) by logistic regression (Newton / IRLS with a
small L2 penalty on the weights, not the bias) over every candidate whose verification is valid,
then reports, per field left out, the held-out precision and recall at 0.5 and a reliability
table (predicted vs observed frequency per confidence bin). Prints the weights in the order of
VerificationConfig (include/sonar3d/recog/verify.hpp).

Relief evidence (`verification.evidence`, when the CSV has it): a placement is refused below
VerificationConfig::min_evidence whatever its confidence. The held-out figures apply that gate
(--min-evidence, default 0.85), and per field left out the script prints the lowest evidence of
a true candidate on the other fields: the gate must stay below it in every fold. By default the
logistic model has the five terms of before; --with-evidence adds the evidence to it as a sixth
term (measured on the recog28d candidates: no held-out gain, one more look-alike above 0.5).
"""
import csv
import math
import sys

import numpy as np

TERMS = ["seen", "explained", "violation", "unexplained", "spill"]


def load(path):
    """(field, terms, label, evidence or None) per valid 2D candidate."""
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r.get("method", "2d") not in ("2d", ""):
                continue
            if r.get("verification.valid", "") not in ("1", "True", "true", "1.0"):
                continue
            try:
                x = [float(r["verification." + t]) for t in TERMS]
            except (KeyError, ValueError):
                continue
            if not all(math.isfinite(v) for v in x):
                continue
            try:
                ev = float(r["verification.evidence"])
            except (KeyError, ValueError):
                ev = None
            rows.append((r.get("field", ""), x, int(float(r["label"])), ev))
    return rows


def fit(X, y, l2):
    """Logistic regression by Newton's method; X without the bias column."""
    A = np.hstack([np.ones((X.shape[0], 1)), X])
    w = np.zeros(A.shape[1])
    P = l2 * np.eye(A.shape[1])
    P[0, 0] = 0.0
    for _ in range(100):
        p = 1.0 / (1.0 + np.exp(-A @ w))
        g = A.T @ (p - y) + P @ w
        H = A.T @ (A * (p * (1 - p))[:, None]) + P + 1e-9 * np.eye(A.shape[1])
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return w


def predict(w, X):
    return 1.0 / (1.0 + np.exp(-(w[0] + X @ w[1:])))


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    l2 = 0.01
    if "--l2" in sys.argv:
        l2 = float(sys.argv[sys.argv.index("--l2") + 1])
    min_evidence = 0.85
    if "--min-evidence" in sys.argv:
        min_evidence = float(sys.argv[sys.argv.index("--min-evidence") + 1])
    if "--with-evidence" in sys.argv:
        TERMS.append("evidence")
    rows = load(sys.argv[1])
    if len(rows) < 10:
        sys.exit(f"calibrate_confidence: {sys.argv[1]}: only {len(rows)} labelled 2D candidates "
                 "with a valid verification; need at least 10")
    fields = sorted({r[0] for r in rows})
    X = np.array([r[1] for r in rows])
    y = np.array([r[2] for r in rows], dtype=float)
    has_ev = any(r[3] is not None for r in rows)  # rows without it pass the gate
    ev = np.array([r[3] if r[3] is not None else 1.0 for r in rows])
    gate = ev >= min_evidence if has_ev else np.ones(len(rows), dtype=bool)
    w = fit(X, y, l2)
    print(f"{len(rows)} candidates ({int(y.sum())} true, {int(len(y) - y.sum())} false), "
          f"{len(fields)} fields")
    print("weights (VerificationConfig): bias = %.3f" % w[0])
    for t, v in zip(TERMS, w[1:]):
        print(f"  w_{t} = {v:.3f}")
    # Held out by field: is the threshold 0.5 right on fields the fit did not see?
    gated = f" and evidence >= {min_evidence}" if has_ev else " (no evidence column)"
    print(f"\nleave-one-field-out at confidence >= 0.5{gated}:")
    print("| field held out | candidates | true | found right | found wrong | missed | "
          "lowest true evidence on the other fields |")
    print("|---|---|---|---|---|---|---|")
    tp = fp = fn = 0
    held = np.zeros(len(rows))
    for f in fields:
        test = np.array([r[0] == f for r in rows])
        if test.all():
            continue
        wf = fit(X[~test], y[~test], l2)
        p = predict(wf, X[test])
        held[test] = p
        acc = (p >= 0.5) & gate[test]
        a, b, c = (int((acc & (y[test] == 1)).sum()), int((acc & (y[test] == 0)).sum()),
                   int((~acc & (y[test] == 1)).sum()))
        tp, fp, fn = tp + a, fp + b, fn + c
        train_true = (~test) & (y == 1)
        known = train_true & np.array([r[3] is not None for r in rows])
        low = "%.3f" % ev[known].min() if known.any() else "–"
        print(f"| {f} | {int(test.sum())} | {int(y[test].sum())} | {a} | {b} | {c} | {low} |")
    if tp + fp > 0 and tp + fn > 0:
        print(f"held-out precision {tp / (tp + fp):.3f}, recall {tp / (tp + fn):.3f} "
              "(of the candidates the search proposed)")
    print("\nreliability (held-out confidence bins):")
    print("| confidence | candidates | observed true fraction |")
    print("|---|---|---|")
    for lo in np.arange(0.0, 1.0, 0.2):
        m = (held >= lo) & (held < lo + 0.2 + (1e-9 if lo >= 0.8 else 0))
        if m.sum():
            print(f"| {lo:.1f}-{lo + 0.2:.1f} | {int(m.sum())} | {y[m].mean():.2f} |")


if __name__ == "__main__":
    main()
