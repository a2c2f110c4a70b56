#!/usr/bin/env python3
"""The peer of `ipa-sysid bench oe`: SysIdentPy's FROLS (forward-regression orthogonal least squares with
AIC order selection) on the same records and the same regressors as the output-error benchmark.

    python scripts/bench_sysidentpy.py --data-dir DATA [--repetitions 3] [--json OUT|-]

Needs `sysidentpy` (PyPI), e.g. in a venv under target/ (never committed):

    python3 -m venv target/bench-venv && target/bench-venv/bin/pip install sysidentpy
    target/release/ipa-sysid bench oe --data-dir DATA --peer target/bench-venv/bin/python   # both in one run

DATA is the folder holding the public benchmark records emps/DATA_EMPS.csv and silverbox/SNLS80mV.csv
(nonlinearbenchmark.org); they are not part of the project.

Cases (as `sysid_studies::oe_bench::OE_CASES`): EMPS `vir` -> `qm`, all 24 841 rows, ARX(6,5,0) with a
constant; silverbox `V1` -> `V2`, rows [40650, 105712), ARX(7,9,0). The candidate terms are the linear
ARX regressors (Polynomial basis of degree 1: y(k-1..k-na), u(k-nk..k-nk-nb+1) and the constant, which
SysIdentPy always offers); FROLS picks the terms by their error-reduction ratio and the number of terms by
AIC among all candidates. SysIdentPy's input lags start at 1, so for nk = 0 the input is advanced by one
sample (its lag 1 is u(k)) and the last sample is dropped: the regressors are those of ARX(na, nb, 0).

Timed: `model.fit` (best and median of the repetitions after one untimed run). Fit % = 100 (1 - |y - yhat|
/ |y - mean(y)|) of the free-run simulation (`predict` with the measured first max-lag outputs as initial
conditions), over the samples after those initial ones; the simulation is timed too.
"""
import argparse
import csv
import json
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

CASES = [
    dict(name="emps", file="emps/DATA_EMPS.csv", u="vir", y="qm", rows=None, na=6, nb=5, nk=0),
    dict(name="silverbox", file="silverbox/SNLS80mV.csv", u="V1", y="V2", rows=(40650, 105712), na=7, nb=9, nk=0),
]


def read(path, ucol, ycol, rows):
    with open(path, newline="") as f:
        r = csv.DictReader(f)
        data = [(float(row[ucol]), float(row[ycol])) for row in r]
    if rows:
        data = data[rows[0]:rows[1]]
    a = np.asarray(data)
    return a[:, 0], a[:, 1]


def fit_percent(y, yhat):
    den = np.linalg.norm(y - y.mean())
    return None if den == 0 else float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den))


def run_case(case, data_dir, reps):
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares

    path = Path(data_dir) / case["file"]
    if not path.is_file():
        return {"skipped": f"{path} not found"}
    u, y = read(path, case["u"], case["y"], case["rows"])
    n = len(u)
    if case["nk"] == 0:
        u, y = u[1:], y[:-1]  # u_shifted(k - 1) = u(k): SysIdentPy's lag 1 is the current input
        xlag = case["nb"]
    else:
        xlag = list(range(case["nk"], case["nk"] + case["nb"]))
    X, Y = u.reshape(-1, 1), y.reshape(-1, 1)
    candidates = case["na"] + case["nb"] + 1

    def make():
        return FROLS(
            order_selection=True,
            n_info_values=candidates,
            ylag=case["na"],
            xlag=xlag,
            info_criteria="aic",
            estimator=LeastSquares(),
            basis_function=Polynomial(degree=1),
        )

    make().fit(X=X, y=Y)  # warm-up
    times = []
    model = None
    for _ in range(reps):
        model = make()
        t = time.perf_counter()
        model.fit(X=X, y=Y)
        times.append(time.perf_counter() - t)
    t = time.perf_counter()
    yhat = model.predict(X=X, y=Y).ravel()
    sim_s = time.perf_counter() - t
    lag = model.max_lag
    m = min(len(yhat), len(y))
    return {
        "samples": n,
        "seconds": min(times),
        "median_seconds": statistics.median(times),
        "simulation_seconds": sim_s,
        "terms": int(len(model.final_model)),
        "candidate_terms": candidates,
        "fit_sim_percent": fit_percent(y[lag:m], yhat[lag:m]),
        "repetitions": reps,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data-dir", required=True, help="folder with emps/ and silverbox/")
    ap.add_argument("--repetitions", type=int, default=3)
    ap.add_argument("--json", help="write the result as JSON here ('-' for standard output)")
    a = ap.parse_args()
    import sysidentpy

    out = {
        "peer": "SysIdentPy FROLS (Polynomial degree 1, LeastSquares, AIC)",
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "sysidentpy": sysidentpy.__version__,
        },
        "cases": {c["name"]: run_case(c, a.data_dir, max(1, a.repetitions)) for c in CASES},
    }
    text = [f"{out['peer']}, versions {out['versions']}:"]
    for name, r in out["cases"].items():
        if "skipped" in r:
            text.append(f"  {name:<10} skipped: {r['skipped']}")
        else:
            text.append(
                f"  {name:<10} {r['samples']} samples: fit {r['seconds']:.3f} s (median {r['median_seconds']:.3f}), "
                f"{r['terms']} of {r['candidate_terms']} terms, free-run fit {r['fit_sim_percent']:.2f} %"
            )
    print("\n".join(text), file=sys.stderr if a.json == "-" else sys.stdout)
    if a.json:
        body = json.dumps(out, indent=2)
        if a.json == "-":
            print(body)
        else:
            Path(a.json).write_text(body + "\n")


if __name__ == "__main__":
    main()
