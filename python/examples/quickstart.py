"""Notebook-style walk through ipa_sysid: simulate the physics IPA, identify a Hammerstein model on one
record, validate it on another, look at its poles, simulate and predict, save it for the command line,
and close a PI loop around it. Run: python python/examples/quickstart.py (writes model.json in the
current directory)."""

import numpy as np

import ipa_sysid

# %% Two experiments on the built-in physics IPA (2000 samples of the paper's staircase at 0.01 s).
t, u, y, pressures = ipa_sysid.simulate_plant("ipa", seed=1)
_, u_val, y_val, _ = ipa_sysid.simulate_plant("ipa", seed=2)
print(f"{len(u)} samples, Ts = {t[1] - t[0]} s, y from {y.min():.2f} to {y.max():.2f} mm")

# %% Identify (output error; the paper's own method is method="rls") and validate.
fit = ipa_sysid.identify(u, y, 0.01, method="oe", validation=(u_val, y_val))
print(fit)
print(fit.model)  # the model as equations with units
print("deadzone:", {k: round(v, 6) for k, v in fit.model.deadzone.items()})
print("a:", np.round(fit.model.a, 6), " poles:", np.round(fit.poles, 6), " stable:", fit.stable)
m = fit.metrics
print(
    "fit % (simulation, validation): "
    f"{m['estimation']['fit_sim_percent']:.4f}, {m['validation']['fit_sim_percent']:.4f}"
)
# Reasons not to trust the model blindly (also issued as IpaSysidWarning).
for w in fit.warnings:
    print("remark:", w)

# %% Free-run simulation and 10-step prediction on the validation record.
y_sim = fit.model.simulate(u_val, y0=y_val)
y_10 = fit.model.predict(u_val, y_val, horizon=10)
# The RMSE over the samples k >= k0 that the model computes, as `validate` and `identify` report it:
# the first k0 are initial conditions (y_val's own for simulate; for this output-error model's
# predict, those estimated to fit the record).
k0 = fit.model.k0


def rmse(y_model):
    return np.sqrt(np.mean((y_model[k0:] - y_val[k0:]) ** 2))


print(f"RMSE over k >= k0 = {k0}: simulation from the measured y0 {rmse(y_sim):.4f} mm, "
      f"10-step prediction {rmse(y_10):.4f} mm")

# %% Save for the command line (ipa-sysid validate --model model.json --data val.csv) and reload.
fit.model.save("model.json")
assert ipa_sysid.load_model("model.json") == fit.model

# %% PI control (Kp = 14, Ki = 1) of the identified model to 50 mm (a Model object or "model:model.json").
c = ipa_sysid.control(fit.model, setpoint=50, duration=10)
step = c["metrics"]
shown = {k: v if v is None else round(v, 4) for k, v in step.items() if k != "settling_time_s"}
print("step metrics:", shown)
settling = step["settling_time_s"]
print("settling time (2 %):", "not settled" if settling is None else f"{settling:.4f} s")
# Why (also issued as IpaSysidWarning): a step not settled has no final overshoot or steady-state error.
for w in c["warnings"]:
    print("remark:", w)
