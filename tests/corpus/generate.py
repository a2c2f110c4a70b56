#!/usr/bin/env python3
"""Regenerates the bad-input corpus (tests/corpus). Run from anywhere: python3 tests/corpus/generate.py

Every file is small and deterministic. The data come from the paper's Hammerstein model (Table III,
normalised b1 = 1) driven by a staircase, computed here independently of the Rust code.
"""
import json
import os

HERE = os.path.dirname(os.path.abspath(__file__))
LEVELS = [200, -120, 0.5, 255, -255, 60, -30, 1, -90, 140, -4, 25]
N = 150


def paper_record(n=N):
    u = [LEVELS[(k // 9) % len(LEVELS)] for k in range(n)]
    bl, br, ml, mr = -1.5, 1.41, 3.46 * 15.67e-4, 2.38 * 15.67e-4

    def dz(v):
        return mr * (v - br) if v >= br else (ml * (v - bl) if v <= bl else 0.0)

    a = [-1.869, 0.9976, -0.1284]
    y = [0.0] * n
    for k in range(1, n):
        v = dz(u[k - 1])
        for i in range(3):
            if k > i:
                v -= a[i] * y[k - 1 - i]
        y[k] = v
    return u, y


def rows(u, y, fmt="{t},{u},{y}"):
    return [fmt.format(t=f"{k * 0.01:.2f}", u=u[k], y=repr(y[k])) for k in range(len(u))]


def write(rel, text, mode="w"):
    path = os.path.join(HERE, rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, mode, newline="" if mode == "w" else None) as f:
        f.write(text)


u, y = paper_record()
plain = "t,u,y\n" + "\n".join(rows(u, y)) + "\n"
write("good.csv", plain)

# ---- bad CSV files -------------------------------------------------------------------------------
write("csv/empty.csv", "")
write("csv/header_only.csv", "t,u,y\n")
write("csv/missing_column.csv", "t,u\n0.00,1\n0.01,2\n0.02,3\n")
write("csv/duplicate_column.csv", "t,u,y,u\n0.00,1,2,3\n0.01,1,2,3\n")
write("csv/text_cell.csv", "t,u,y\n0.00,1,2\n0.01,abc,3\n0.02,1,2\n")
write("csv/empty_cell.csv", "t,u,y\n0.00,1,2\n0.01,1,\n0.02,1,2\n")
write("csv/nan_cell.csv", "t,u,y\n0.00,1,2\n0.01,1,2\n0.02,NaN,2\n")
write("csv/inf_cell.csv", "t,u,y\n0.00,1,2\n0.01,1,-inf\n0.02,1,2\n")
write("csv/ragged_row.csv", "t,u,y\n0.00,1,2\n0.01,1,2,7\n0.02,1,2\n")
write("csv/short_row.csv", "t,u,y\n0.00,1,2\n0.01,1\n0.02,1,2\n")
write("csv/nonuniform_time.csv", "t,u,y\n0.00,1,2\n0.01,1,2\n0.02,1,2\n0.04,1,2\n0.05,1,2\n")
# A logger's millisecond clock read as seconds: typical step 10 "s", one of 11.
write("csv/millisecond_time.csv", "t,u,y\n0,1,2\n10,1,2\n20,1,2\n31,1,2\n41,1,2\n51,1,2\n")
write("csv/decreasing_time.csv", "t,u,y\n0.00,1,2\n0.01,1,2\n0.02,1,2\n0.015,1,2\n0.03,1,2\n")
write("csv/repeated_time.csv", "t,u,y\n0.00,1,2\n0.01,1,2\n0.01,1,2\n0.02,1,2\n")
write("csv/too_few_samples.csv", "\n".join(plain.splitlines()[:7]) + "\n")
write("csv/no_header.csv", "\n".join(rows(u[:20], y[:20])) + "\n")
# Constant input: the Hammerstein deadzone needs both signs; for ARX, u = 50 with y at its steady
# state makes y(k-1) and u(k-1) proportional (rank deficient).
write("csv/constant_input.csv", "t,u,y\n" + "".join(f"{k * 0.01:.2f},50,{y[k]!r}\n" for k in range(N)))
write("csv/constant_steady.csv", "t,u,y\n" + "".join(f"{k * 0.01:.2f},50,20\n" for k in range(N)))
# Binary garbage: invalid UTF-8 on line 2, and a NUL byte in otherwise ASCII text.
garbage = bytes((k * 151 + 7) % 256 for k in range(300))
write("csv/binary_garbage.csv", b"t,u,y\n" + garbage, mode="wb")
write("csv/nul_byte.csv", b"t,u,y\n0.00,1,2\n0.01,1\x002\n", mode="wb")
# Finite but huge values: accepted by the reader; RLS must fail at a named sample (overflow), never NaN.
write("csv/overflow.csv", "t,u,y\n" + "".join(f"{k * 0.01:.2f},{u[k] * 1e300!r},{y[k] * 1e300!r}\n" for k in range(N)))
# Finite but tiny values: the squares underflow to 0, the estimate is not determined.
write("csv/underflow.csv", "t,u,y\n" + "".join(f"{k * 0.01:.2f},{u[k] * 1e-200!r},{y[k] * 1e-200!r}\n" for k in range(N)))

# ---- accepted variants of good.csv (must read as the same numbers) ----------------------------------
write("accepted/semicolon.csv", plain.replace(",", ";"))
write("accepted/tab.csv", plain.replace(",", "\t"))
write("accepted/crlf.csv", plain.replace("\n", "\r\n"))
write("accepted/bom.csv", b"\xef\xbb\xbf" + plain.encode(), mode="wb")
write("accepted/quoted.csv", '"t","u","y"\n' + "\n".join(
    f'"{r.split(",")[0]}",{r.split(",")[1]},"{r.split(",")[2]}"' for r in rows(u, y)) + "\n")
write("accepted/spaces.csv", "  t , u ,y  \n" + "\n".join(" " + r.replace(",", " ,  ") + "  " for r in rows(u, y)) + "\n")
write("accepted/trailing_empty.csv", "t,u,y,,\n" + "\n".join(r + ",," for r in rows(u, y)) + "\n")
write("accepted/blank_lines.csv", "t,u,y\n\n" + "\n\n".join(rows(u, y)) + "\n\n\n")
write("accepted/extra_columns.csv", "index,t,comment,u,y\n" + "\n".join(
    f"{k},{r.split(',')[0]},ok,{r.split(',')[1]},{r.split(',')[2]}" for k, r in enumerate(rows(u, y))) + "\n")
write("accepted/decimal_comma.csv", "t;u;y\n" + "\n".join(
    r.replace(",", ";").replace(".", ",") for r in rows(u, y)) + "\n")

# ---- model files -------------------------------------------------------------------------------------
good_model = {
    "format": "ipa-sysid-model",
    "version": 1,
    "model": {
        "kind": "hammerstein", "ts": 0.01, "na": 3, "nb": 1, "nk": 1,
        "a": [-1.869, 0.9976, -0.1284], "b": [1.0], "offset": None,
        "deadzone": {"b_l": -1.5, "b_r": 1.41, "m_l": 3.46 * 15.67e-4, "m_r": 2.38 * 15.67e-4},
    },
}


def model_variant(rel, change):
    m = json.loads(json.dumps(good_model))
    change(m)
    write(rel, json.dumps(m, indent=2) + "\n")


write("good_model.json", json.dumps(good_model, indent=2) + "\n")
model_variant("model/wrong_schema.json", lambda m: m.update({"model": {"poles": [0.5, 0.2]}}))
write("model/not_a_model.json", json.dumps({"hello": [1, 2, 3]}) + "\n")
write("model/array.json", "[1, 2, 3]\n")
write("model/empty.json", "")
full = json.dumps(good_model, indent=2)
write("model/truncated.json", full[: len(full) // 2])
model_variant("model/nan_coefficients.json", lambda m: m["model"].update({"a": [float("nan"), 0.9976, -0.1284]}))
model_variant("model/wrong_length.json", lambda m: m["model"].update({"a": [-1.869, 0.9976]}))
model_variant("model/huge_order.json", lambda m: m["model"].update({"na": 1000000}))
model_variant("model/unknown_field.json", lambda m: m["model"].update({"poles": [0.5]}))
model_variant("model/wrong_type.json", lambda m: m["model"].update({"ts": "10 ms"}))
model_variant("model/negative_ts.json", lambda m: m["model"].update({"ts": -0.01}))
model_variant("model/newer_version.json", lambda m: m.update({"version": 99}))
model_variant("model/other_format.json", lambda m: m.update({"format": "matlab-idpoly"}))
model_variant("model/hammerstein_without_deadzone.json", lambda m: m["model"].pop("deadzone"))
# An unstable model whose simulation overflows f64 (numerical failure, exit 1).
model_variant("model/unstable.json", lambda m: m["model"].update(
    {"kind": "arx", "a": [-1e10, 0.0, 0.0], "b": [1.0], "deadzone": None}))
model_variant("model/zero_poles.json", lambda m: m["model"].update({"a": [0.0, 0.0, 0.0]}))
