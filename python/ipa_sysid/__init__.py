"""ipa_sysid: system identification, simulation and PI control of the Intelligent Pneumatic Actuator.

The numbers are computed by the Rust libraries of ipa-sysid (the same code as the ``ipa-sysid`` command
line), so that ``identify(...).to_dict()`` is the document ``ipa-sysid identify --json`` writes for the
same data and options.

- ``identify(u, y, ts, ...)`` -> ``Fit`` (``.model``, ``.poles``, ``.stable``, ``.metrics``,
  ``.warnings``, ``.residuals``, ``.to_dict()``)
- ``Model`` (``.a``, ``.b``, ``.deadzone``, ``.ts``, ``.simulate``, ``.predict``, ``.save``,
  ``.to_control``), ``load_model(path)``, ``paper_model()``
- ``Rls(n, forgetting, p0)`` (``.update``, ``.update_many``, ``.theta``, ``.P``)
- ``calibrate(data, validation=None, free=None, ...)`` -> dict: the physics plant fitted to a record
  (a digital twin, as ``ipa-sysid calibrate``)
- ``simulate_plant(plant, ...)`` -> ``(t, u, y, pressures)``; ``control(plant, setpoint=...)`` -> dict

Bad input raises ``ValueError`` with the command line's message; a numerical failure raises
``ArithmeticError``. See docs/python.md in the repository.
"""

from ._core import (
    Fit,
    Model,
    Rls,
    __version__,
    calibrate,
    control,
    identify,
    load_model,
    paper_model,
    simulate_plant,
)

__all__ = [
    "Fit",
    "Model",
    "Rls",
    "__version__",
    "calibrate",
    "control",
    "identify",
    "load_model",
    "paper_model",
    "simulate_plant",
]
