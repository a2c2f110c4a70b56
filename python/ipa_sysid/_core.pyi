"""Type stubs of the compiled module ipa_sysid._core (see ipa_sysid for the overview)."""

from os import PathLike
from typing import Any, Literal, Sequence

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]

__version__: str

class Model:
    """An identified or loaded model: A(q) y(k) = B(q) x(k - nk) + c, x = u (ARX) or the deadzone f(u)."""

    @property
    def kind(self) -> Literal["hammerstein", "arx"]:
        """"hammerstein" or "arx"."""
    @property
    def a(self) -> FloatArray:
        """A(q) coefficients [a1, ..., a_na]."""
    @property
    def b(self) -> FloatArray:
        """B(q) coefficients [b1, ..., b_nb]."""
    @property
    def na(self) -> int:
        """na: number of poles."""
    @property
    def nb(self) -> int:
        """nb: number of B coefficients."""
    @property
    def nk(self) -> int:
        """nk: input delay in samples."""
    @property
    def k0(self) -> int:
        """k0 = max(na, nk + nb - 1): initial outputs a simulation takes as given."""
    @property
    def ts(self) -> float:
        """Ts: sampling period in s."""
    @property
    def offset(self) -> float | None:
        """c: constant term, or None."""
    @property
    def deadzone(self) -> dict[str, float] | None:
        """{"b_l", "b_r", "m_l", "m_r"} for Hammerstein, None for ARX."""
    @property
    def poles(self) -> ComplexArray:
        """Poles of the linear block."""
    @property
    def stable(self) -> bool:
        """All poles strictly inside the unit circle."""
    @property
    def parameter_count(self) -> int:
        """p: number of estimated parameters."""
    @property
    def data_range(self) -> dict[str, Any] | None:
        """{"u": [[min, max] per input], "y": [min, max]} of the estimation data, or None (read-only)."""
    def simulate(self, u: ArrayLike, y0: ArrayLike | float | None = None) -> FloatArray:
        """Free-run simulation of len(u) samples; the first k0 outputs from y0 (an output record, or one
        number: at rest there), zeros with an IpaSysidWarning when None."""
    def predict(self, u: ArrayLike, y: ArrayLike, horizon: int = 1) -> FloatArray:
        """k-step-ahead prediction from measured u and y."""
    def metrics(
        self,
        u: ArrayLike,
        y: ArrayLike,
        name: str = "data",
        score_from: int | None = None,
        resid_lags: int = 25,
    ) -> dict[str, Any]:
        """Validation metrics (fit %, RMSE, loss, FPE, AIC; MATLAB's loss_fcn, fpe_matlab, aic_matlab;
        N, p) on a record, as `validate`, with its warnings and its residual analysis ("residuals",
        resid_lags lags as `validate --resid-lags`); score_from=K scores the samples k >= max(K, k0)
        only, as `validate --score-from K` (the dict's "score_from" is that first scored sample)."""
    def to_json(self) -> str:
        """The model file text (`identify --save-model` format)."""
    @staticmethod
    def from_json(text: str | bytes) -> Model:
        """A model from its model-file text (`to_json()`), checked and warned of as `load_model`.
        Models, Fits and NarxFits pickle and deep-copy (through this text)."""
    def save(self, path: str | bytes | PathLike[str] | PathLike[bytes], force: bool = False) -> None:
        """Writes the model file as the command line writes its outputs: a file atomically, a device or
        FIFO directly (never replaced); an existing file only when it is a model file (or empty) and a
        symbolic link not at all, unless force=True (the command line's --force); a folder, or a file of
        another kind, is a ValueError naming `path`."""
    def frequency_response(
        self,
        points: int = 20,
        f_min_hz: float | None = None,
        samples: int = 20,
        kp: float | None = None,
        ki: float | None = None,
        controller: dict[str, Any] | str | PathLike[str] | None = None,
    ) -> dict[str, Any]:
        """Bode table, DC gain, poles, zeros, impulse and step response (and the margins of a PI, or of a
        tuned controller as control(controller=...) takes it): as `ipa-sysid response --json`."""
    def to_control(self, side: Literal["right", "left"] | None = None) -> Any:
        """The linear block as a python-control TransferFunction (ImportError without python-control)."""
    def transfer_polynomials(self) -> tuple[list[float], list[float]]:
        """(num, den) of the linear block in descending powers of z."""
    def __str__(self) -> str:
        """The model as equations with units."""
    def __eq__(self, other: object) -> bool: ...

class Fit:
    """The result of identify()."""

    @property
    def model(self) -> Model:
        """The fitted model."""
    @property
    def poles(self) -> ComplexArray:
        """Poles, largest modulus first."""
    @property
    def stable(self) -> bool:
        """All poles strictly inside the unit circle."""
    @property
    def metrics(self) -> dict[str, Any]:
        """{"estimation": {...}, "validation": {...}} as in identify --json."""
    @property
    def fit_sim_percent(self) -> float | None:
        """Simulation fit % on the estimation record (metrics["estimation"]["fit_sim_percent"])."""
    @property
    def fit_pred_percent(self) -> float | None:
        """One-step prediction fit % on the estimation record."""
    @property
    def parameters(self) -> list[dict[str, Any]]:
        """[{"name", "value", "std"}] as in identify --json."""
    @property
    def params(self) -> dict[str, float]:
        """The estimates by name ("input.name" with several inputs)."""
    def parameters_frame(self) -> Any:
        """The parameters as a pandas DataFrame indexed by name (value, std[, input])."""
    @property
    def estimation(self) -> dict[str, Any]:
        """The `estimation` object of identify --json."""
    @property
    def warnings(self) -> list[Any]:
        """Reasons not to trust the estimate."""
    @property
    def residuals(self) -> dict[str, Any] | None:
        """Residual analysis of identify --json, when reported."""
    def to_dict(self) -> dict[str, Any]:
        """The identify --json document."""
    def to_json(self) -> str:
        """The identify --json document as text."""

class NarxFit:
    """The result of identify(..., structure="narx"): a polynomial NARX model."""

    @property
    def terms(self) -> list[dict[str, Any]]:
        """[{"term", "coefficient", "std", "err"}] in FROLS order."""
    @property
    def metrics(self) -> dict[str, Any]:
        """{"estimation": {...}, "validation": {...}} as in identify --json."""
    @property
    def warnings(self) -> list[str]:
        """Reasons not to trust the model."""
    def to_dict(self) -> dict[str, Any]:
        """The identify --structure narx --json document."""
    def to_json(self) -> str:
        """The identify --structure narx --json document as text."""
    def model_file(self) -> str:
        """The model file text (identify --save-model format)."""

class Rls:
    """Recursive least squares (paper eqs. 9-12) on n parameters."""

    def __init__(self, n: int, forgetting: float = 1.0, p0: float = 1e6) -> None: ...
    @property
    def n(self) -> int:
        """Number of parameters."""
    @property
    def forgetting(self) -> float:
        """Forgetting factor rho."""
    @property
    def samples(self) -> int:
        """Updates applied so far."""
    @property
    def theta(self) -> FloatArray:
        """Current estimate (copy)."""
    @property
    def P(self) -> FloatArray:
        """n x n covariance-like matrix (copy)."""
    def update(self, phi: ArrayLike, y: float) -> float:
        """One update; returns the a-priori error."""
    def update_many(self, Phi: ArrayLike, y: ArrayLike) -> FloatArray:
        """Updates with each row of Phi (N x n); returns the a-priori errors."""
    def restart_covariance(self, p0: float) -> None:
        """P = p0 I, keeping theta."""

def identify(
    u: ArrayLike,
    y: ArrayLike,
    ts: float,
    model: Literal["hammerstein", "arx"] = "hammerstein",
    method: Literal["rls", "ls", "oe", "iv"] | None = None,
    na: int = 3,
    nb: int = 1,
    nk: int = 1,
    forgetting: float = 1.0,
    p0: float = 1e6,
    offset: bool = False,
    validation: tuple[ArrayLike, ArrayLike] | Sequence[ArrayLike] | None = None,
    passes: int | None = None,
    max_iterations: int = 100,
    rls_form: Literal["standard", "ud"] = "standard",
    windup: Literal["none", "trace", "directional"] = "none",
    max_trace: float | None = None,
    iv_stages: int = 10,
    name: str = "data",
    validation_name: str = "validation",
    resid_lags: int = 25,
    fallback: bool = False,
    nonlinearity: Literal[
        "linear", "deadzone", "saturation", "deadzone-saturation", "piecewise-linear", "polynomial"
    ] | None = None,
    breakpoints: int | Literal["auto"] | None = None,
    degree: int | None = None,
    output_nonlinearity: Literal["saturation", "piecewise-linear", "polynomial"] | None = None,
    structure: Literal["hammerstein", "arx", "narx"] | None = None,
    stop: Literal["sim", "aic", "bic"] = "sim",
    max_terms: int = 30,
    refine: bool = True,
    detrend: Literal["none", "mean", "linear"] = "none",
    max_memory_gb: float = 4.0,
) -> Fit | NarxFit:
    """Identifies a model as `ipa-sysid identify` does with the same options (structure="narx":
    a polynomial NARX model of degree `degree`, default 2, a NarxFit)."""

def load_model(path: str | bytes | PathLike[str] | PathLike[bytes]) -> Model:
    """Reads a model file of `identify --save-model`."""

def paper_model() -> Model:
    """The paper's Table III Hammerstein model."""

def simulate_plant(
    plant: str | bytes | PathLike[str] = "ipa",
    input: str = "staircase",
    samples: int | None = None,
    seed: int = 0,
    amplitude: float = 255.0,
    ts: float | None = None,
    x0: float | None = None,
    noise_std: float = 0.0,
    plant_config: str | bytes | PathLike[str] | None = None,
    max_memory_gb: float = 4.0,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
    """One open-loop experiment as `ipa-sysid simulate`: (t, u, y, pressures)."""

def calibrate(
    data: str | bytes | PathLike[str],
    validation: str | bytes | PathLike[str] | None = None,
    free: str | None = None,
    fixed: str | None = None,
    plant_config: str | bytes | PathLike[str] | None = None,
    segment: float = 0.5,
    max_iterations: int = 40,
    ts: float | None = None,
    u_col: str = "u",
    y_col: str = "y",
    t_col: str = "t",
    no_header: bool = False,
    val_u_col: str | None = None,
    val_y_col: str | None = None,
    max_memory_gb: float = 4.0,
) -> dict[str, Any]:
    """The physics plant calibrated to a record as `ipa-sysid calibrate`: estimates, fits, warnings, toml."""

def control(
    plant: str | Model | None = None,
    setpoint: float | None = None,
    profile: str | Sequence[tuple[float, float]] | Any | None = None,
    kp: float = 14.0,
    ki: float = 1.0,
    duration: float | None = None,
    y0: float = 0.0,
    integral: Literal["scaled", "per-sample"] = "scaled",
    anti_windup: Literal["none", "clamping", "back-calculation"] = "none",
    tracking_time: float | None = None,
    u_max: float = 255.0,
    compensate_deadzone: Model | Literal["paper"] | None = None,
    compensator_slopes: Literal["shift", "equalise"] = "shift",
    compensator_threshold: float = 0.0,
    plant_config: str | bytes | PathLike[str] | None = None,
    controller: str | PathLike[str] | None = None,
) -> dict[str, Any]:
    """Closed-loop PI control as `ipa-sysid control`: trace arrays, metrics, steps. `controller`: the
    JSON text of a controller file or its path, read as `control --controller` reads it (the wrapper also
    takes tune()'s dict)."""

def tune(
    model: Model | str | PathLike[str] | None = None,
    plant_config: str | bytes | PathLike[str] | None = None,
    spec: str = "",
    variants: int = 5,
    max_evaluations: int = 150,
    check_physics: bool = False,
    physics_variants: int = 20,
) -> dict[str, Any]:
    """The position controller tuned as `ipa-sysid tune --json`, plus "controller_file" (its text)."""

def fleet_windows(
    u: ArrayLike,
    y: ArrayLike,
    offsets: list[int],
    ts: float,
    window: int,
    method: str = "ls",
    na: int = 3,
    nb: int = 1,
    nk: int = 1,
    detect_warmup: int = 200,
    detect_calibration: int = 800,
) -> dict[str, Any]:
    """Every window of a partition identified (LS) and tracked: the columns `ipa_sysid.fleet.identify_partition` builds its frame from;
    a window not identified has `error` (the core's message) and, for a sample that is not finite,
    `error_signal` ("u" or "y"), `error_sample` (within the window) and `error_value`."""

def fleet_times(t: ArrayLike, offsets: list[int], ts: float) -> list[tuple[str, float]]:
    """Per actuator (rows offsets[g] .. offsets[g + 1] of t, sorted by time): (error, step): error "" or the
    time column's fault (NaN, not increasing, non-uniform); step the column's typical step (s) where ts
    contradicts it by more than 0.1 %, else NaN."""

def check_output(path: str | PathLike[str], argument: str, force: bool = False) -> None:
    """Refuses an output path as the command line refuses an output flag (a folder, a socket, a link to
    nothing, a read-only file, a link to a file without force: ValueError naming `argument`)."""

def write_output(
    path: str | PathLike[str], data: bytes, argument: str, force: bool = False
) -> None:
    """Writes `data` as the command line writes an output: a file atomically, a device or FIFO
    directly (never replaced); an existing file only by the same kind of file and a symbolic link to a
    file not at all, unless force=True; ValueError naming `argument` or OSError."""
