#!/usr/bin/env python3
"""The peer of `ipa-sysid bench narx`: SysIdentPy's FROLS (polynomial NARX, terms by the error-reduction
ratio, their number by AIC, coefficients by least squares) on the same records, splits, lags and degree.

    python scripts/bench_sysidentpy_narx.py --cases CASES.json [--repetitions 3] [--json OUT|-]

CASES.json (written by `ipa-sysid bench narx`, which runs this script with `--peer PYTHON`) lists each
case: name, estimation and test records as (file, u column, y column, first row, end row), na, nb, nk,
degree, constant. Needs `sysidentpy` (PyPI), e.g. `python3 -m venv /tmp/sip && /tmp/sip/bin/pip install
sysidentpy`.

SysIdentPy's input lags start at 1, so for nk = 0 the input is advanced by one sample (its lag 1 is u(k))
and the last sample is dropped: the candidate regressors are those of (na, nb, nk). SysIdentPy always
offers the constant term. Timed: `model.fit` (best and median of the repetitions after one untimed run).
Test RMSE: free-run simulation (`predict` from the measured first max-lag outputs) over the samples after
those initial ones, as `ipa-sysid identify --structure narx` reports it.
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


def read(spec):
    path, ucol, ycol, start, end = spec
    with open(path, newline="") as f:
        rows = [(float(r[ucol]), float(r[ycol])) for r in csv.DictReader(f) if r[ucol] != ""]
    a = np.asarray(rows[start:end])
    return a[:, 0], a[:, 1]


def run_case(case, reps):
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares
    from math import comb

    for spec in (case["estimation"], case["test"]):
        if not Path(spec[0]).is_file():
            return {"skipped": f"{spec[0]} not found"}
    ue, ye = read(case["estimation"])
    ut, yt = read(case["test"])
    na, nb, nk, d = case["na"], case["nb"], case["nk"], case["degree"]
    if nk == 0:
        ue, ye, ut, yt = ue[1:], ye[:-1], ut[1:], yt[:-1]
        xlag = nb
    else:
        xlag = list(range(nk, nk + nb))
    candidates = comb(na + nb + d, d)

    def make():
        return FROLS(
            order_selection=True,
            n_info_values=min(candidates, case.get("max_terms", 30)),
            ylag=na,
            xlag=xlag,
            info_criteria="aic",
            estimator=LeastSquares(),
            basis_function=Polynomial(degree=d),
        )

    X, Y = ue.reshape(-1, 1), ye.reshape(-1, 1)
    make().fit(X=X, y=Y)  # warm-up
    times, model = [], None
    for _ in range(reps):
        model = make()
        t = time.perf_counter()
        model.fit(X=X, y=Y)
        times.append(time.perf_counter() - t)
    yhat = model.predict(X=ut.reshape(-1, 1), y=yt.reshape(-1, 1)).ravel()
    lag = model.max_lag
    m = min(len(yhat), len(yt))
    err = yt[lag:m] - yhat[lag:m]
    rmse = float(np.sqrt(np.mean(err**2))) if np.all(np.isfinite(err)) else None
    return {
        "samples": int(len(ue)),
        "seconds": min(times),
        "median_seconds": statistics.median(times),
        "terms": int(len(model.final_model)),
        "candidate_terms": candidates,
        "test_rmse_sim": rmse,
        "repetitions": reps,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", required=True, help="the cases as JSON (a file, or - for standard input)")
    ap.add_argument("--repetitions", type=int, default=3)
    ap.add_argument("--json", help="write the result as JSON here ('-' for standard output)")
    a = ap.parse_args()
    import sysidentpy

    cases = json.loads(sys.stdin.read() if a.cases == "-" else Path(a.cases).read_text())
    out = {
        "peer": "SysIdentPy FROLS (Polynomial, LeastSquares, AIC)",
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "sysidentpy": sysidentpy.__version__,
        },
        "cases": {c["name"]: run_case(c, max(1, a.repetitions)) for c in cases},
    }
    text = [f"{out['peer']}, versions {out['versions']}:"]
    for name, r in out["cases"].items():
        if "skipped" in r:
            text.append(f"  {name:<16} skipped: {r['skipped']}")
        else:
            rm = "blew up" if r["test_rmse_sim"] is None else f"{r['test_rmse_sim']:.4g}"
            text.append(
                f"  {name:<16} {r['samples']} samples: fit {r['seconds']:.3f} s (median {r['median_seconds']:.3f}), "
                f"{r['terms']} terms, test RMSE (simulation) {rm}"
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
