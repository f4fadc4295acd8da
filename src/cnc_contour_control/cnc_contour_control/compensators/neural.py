"""Paper 001's online neural contour compensator: one hidden layer, trained at every tick.

The network (Section 2.2), for n axes (the paper's n = 2)::

    z  = [x_r,i(t)·s_p, c_i(t)·s_p, c_i(t−1)·s_p  for each axis i,
          u_N,k(t−1)·s_u  for each axis k,  1]                 4n inputs + a bias (Eq. 20; 8 for n = 2)
    q  = V z,   o_j = f(q_j) = (1 − e^−q)/(1 + e^−q) = tanh(q/2)   L2 bipolar sigmoids (Eq. 5)
    u_N = W [o, 1]                                             n linear outputs, drive units (Eq. 6)

``s_p`` is ``position_input_scale_per_m`` (1000: inputs in mm), ``s_u`` is
``output_input_scale``. The last weight of each row is the paper's threshold ζ.

The learning law (Section 2.3), with errors in the unit set by
``error_scale_per_m`` = s (1000: mm, the paper's)::

    E   = ½ Σ_k (s(r_k − c_k))² + β ½ (s ε_c)²
    δ_k = −s(r_k − c_k) + β s ε_c ∂ε_c/∂c_k           ∂ε_c/∂c = (−sin θ, cos θ, 0, …)
    g_k = δ_k · sign(∂c_k/∂u_k)                       the plant Jacobian replaced by its sign
    ΔW  = −η g [o, 1]ᵀ,   ΔV = −η ((W_o)ᵀ g ⊙ f'(q)) zᵀ,   f'(q) = (1 − f²)/2
    w(t+1) = w(t) + Δw(t) + α Δw(t−1)                  (Eqs. 11, 17: momentum on the previous Δw)

**Sign of ε_c.** Ours is > 0 to the left of travel (``ContourError.msg``), so
∂ε_c/∂c_x = −sin θ and ∂ε_c/∂c_y = cos θ. The paper states sin θ and −cos θ:
that holds if its Eq. 2 measures the offsets e' from P(t) to the reference
point P2*, which makes its ε_c the negative of ours. The product
ε_c·∂ε_c/∂c_k, the only place either enters δ_k, is the same under both
conventions, so the law descends ½ε_c² in both. (Mixing them, our ε_c with
the printed derivatives, would grow |ε_c|.) ``test_compensators`` checks one
update against finite differences of E with ε_c computed from the geometry,
and that a positive ε_c teaches a push to the right.

**Timing.** The error measured at tick t results from the output applied at
t − 1, so at tick t the network first learns from the errors of the sample
through the forward pass it stored at t − 1, then runs the forward pass of t
with the new weights. The first tick of a run only runs forward (and takes
c(t−1) = c(t)). The output weights start at 0: the first run is the PID's.

**Divergence guard.** Non-finite weights or a Euclidean norm of all weights
above ``weight_norm_limit`` after an update (the weights then go back to
those before it), an output at ±``output_limit`` for ``pinned_ticks`` ticks
in a row, or a non-finite output: learning stops, the output is zero from
then on and :attr:`fault` says why. The fault stays through :meth:`reset`;
:meth:`load` of a good file or :meth:`initialise` clears it.

**Learning rate.** η = 0.05 on errors in mm (the paper's, as printed) makes
each tick's update act like an extra integral gain several times the PID's
on paper 001's loop (issue 8); about 100× smaller steps learn within a few
runs, and the default η is 100× smaller. η and s are both stated
parameters: a tick moves the output weights by η·s·e·o for an error e in metres.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cnc_contour_control.compensators.base import CompensatorSample, check_sample, checked_factors, factors_for
from cnc_contour_control.compensators.state_file import FloatArray, load_state, save_state
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param

_WHO = "neural compensator"
#: Paper 001's learning rate as printed (errors in mm); the default is 100 times smaller (module docstring).
PAPER_ETA = 0.05


def bipolar_sigmoid(q: FloatArray, out: FloatArray) -> FloatArray:
    """f(q) = (1 − e^−q)/(1 + e^−q), written as tanh(q/2) (no overflow for any q) into ``out``."""
    np.multiply(q, 0.5, out=out)
    return np.tanh(out, out=out)


@dataclass(frozen=True)
class NeuralConfig:
    """Configuration of the neural compensator (defaults: paper 001's sizes and α; η 100× below the paper's).

    Parameters
    ----------
    hidden_units : int
        Hidden bipolar-sigmoid units L2, in [1, 1000] (paper: 5).
    eta : float
        Learning rate η, in [0, 1e3]; default 5e-4, 100× below the paper's 0.05 on errors in mm
        (:data:`PAPER_ETA`, which destabilises: see the module docstring).
    alpha : float
        Momentum α on the previous tick's Δw, in [0, 0.99] (paper: 0.15).
    beta : float
        Weight β of the contour term E_c, in [0, 1e6].
    position_input_scale_per_m : float
        Scale of the position inputs x_r, c [1/m], in [1e-9, 1e9] (1000: the network sees mm).
    output_input_scale : float
        Scale of the previous outputs as inputs [1/drive unit], in [0, 1e9].
    error_scale_per_m : float
        Unit of the errors in the learning law [1/m], in [1e-9, 1e9] (1000: mm, the paper's).
    jacobian_signs : tuple of float
        sign(∂c_k/∂u_k) per axis, each +1 or −1; empty: +1 on every axis.
    seed : int
        Seed of the initial hidden weights, in [0, 2**32 − 1].
    init_scale : float
        Hidden weights and thresholds start uniform in ±init_scale, in [0, 10]; output weights start at 0.
    output_limit : float
        Clip of each output [drive units], in [1e-9, 1e12].
    weight_norm_limit : float
        Divergence guard: largest Euclidean norm of all weights, in [1e-9, 1e150].
    pinned_ticks : int
        Divergence guard: ticks an output may stay at ±output_limit in a row, in [1, 1e9].
    """

    hidden_units: int = param(5, low=1, high=1000, read_only=True, description="hidden units L2 (paper: 5)")
    eta: float = param(PAPER_ETA / 100.0, low=0.0, high=1.0e3,
                       description="learning rate eta (the paper prints 0.05 on errors in mm, which destabilises)")
    alpha: float = param(0.15, low=0.0, high=0.99, description="momentum alpha on the previous step (paper: 0.15)")
    beta: float = param(1.0, low=0.0, high=1.0e6, description="weight beta of the contour-error term E_c")
    position_input_scale_per_m: float = param(1000.0, unit="1/m", low=1.0e-9, high=1.0e9,
                                              description="scale of the position inputs (1000: mm)")
    output_input_scale: float = param(1.0, unit="1/drive", low=0.0, high=1.0e9,
                                      description="scale of the previous outputs as inputs")
    error_scale_per_m: float = param(1000.0, unit="1/m", low=1.0e-9, high=1.0e9,
                                     description="unit of the errors in the learning law (1000: mm, the paper's)")
    jacobian_signs: tuple[float, ...] = param((), description="sign of dc_k/du_k per axis, +1 or -1 (empty: all +1)")
    seed: int = param(0, low=0, high=2**32 - 1, read_only=True, description="seed of the initial hidden weights")
    init_scale: float = param(0.1, low=0.0, high=10.0, read_only=True,
                              description="initial hidden weights uniform in +-init_scale (output weights 0)")
    output_limit: float = param(100.0, unit="drive", low=1.0e-9, high=1.0e12, description="clip of each output")
    weight_norm_limit: float = param(1.0e6, low=1.0e-9, high=1.0e150,
                                     description="divergence guard: largest norm of all weights")
    pinned_ticks: int = param(1000, low=1, high=1.0e9,
                              description="divergence guard: ticks an output may stay at the limit in a row")

    def __post_init__(self) -> None:
        for name in ("hidden_units", "seed", "pinned_ticks"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ConfigError(f"neural.{name} must be an integer, got {value!r}")
        check_ranges(self, "neural")
        object.__setattr__(self, "jacobian_signs", _signs(self.jacobian_signs))


def _signs(value: object) -> tuple[float, ...]:
    signs = checked_factors("jacobian_signs", value, "neural")
    for k, sign in enumerate(signs):
        if sign not in (1.0, -1.0):
            raise ConfigError(f"neural.jacobian_signs[{k}] must be +1 or -1, got {sign!r}")
    return signs


class NeuralCompensator:
    """Paper 001's network, learning online at every tick (see the module docstring).

    Parameters
    ----------
    config : NeuralConfig
        Validated configuration.
    axis_names : sequence of str
        The axes, in the order of the sample's lists; the first two span the contour plane.
    """

    def __init__(self, config: NeuralConfig, axis_names: Sequence[str]) -> None:
        self.config = config
        self.axis_names = tuple(axis_names)
        if not self.axis_names:
            raise ConfigError("neural compensator needs at least one axis")
        self._signs = factors_for("jacobian_signs", config.jacobian_signs, self.axis_names, "neural")
        self.frozen = False
        self.fault: str | None = None
        self._build_arrays(config.hidden_units, len(self.axis_names))
        self.initialise()
        self.reset()

    def _build_arrays(self, hidden: int, n: int) -> None:
        """Every array of the hot path, once: weights as views of one flat vector, the step's buffers."""
        self.n_inputs = 4 * n
        size_v, size_w = hidden * (self.n_inputs + 1), n * (hidden + 1)
        self._theta = np.zeros(size_v + size_w)
        self._backup, self._gradient, self._momentum = (np.zeros_like(self._theta) for _ in range(3))
        self._v = self._theta[:size_v].reshape(hidden, self.n_inputs + 1)
        self._w = self._theta[size_v:].reshape(n, hidden + 1)
        self._w_hidden_t = self._w[:, :hidden].T
        self._grad_v = self._gradient[:size_v].reshape(self._v.shape)
        self._grad_w = self._gradient[size_v:].reshape(self._w.shape)
        self._z = np.zeros(self.n_inputs + 1)
        self._z[-1] = 1.0
        self._z_row = self._z.reshape(1, -1)
        self._q = np.zeros(hidden)
        self._o = np.ones(hidden + 1)  # the last entry stays 1: the output threshold's input
        self._o_hidden = self._o[:hidden]
        self._o_row = self._o.reshape(1, -1)
        self._u = np.zeros(n)
        self._g = np.zeros(n)
        self._g_column = self._g.reshape(n, 1)
        self._hidden_delta = np.zeros(hidden)
        self._hidden_delta_column = self._hidden_delta.reshape(hidden, 1)
        self._slope = np.zeros(hidden)
        self._zeros = [0.0] * n

    def initialise(self) -> None:
        """Hidden weights uniform in ±init_scale from ``seed``, output weights 0; clears the fault."""
        rng = np.random.default_rng(self.config.seed)
        self._v[:] = rng.uniform(-self.config.init_scale, self.config.init_scale, self._v.shape)
        self._w[:] = 0.0
        self.fault = None
        self._momentum[:] = 0.0

    @property
    def input_weights(self) -> FloatArray:
        """V with the hidden thresholds as its last column, shape (L2, 4n + 1) (a copy)."""
        return self._v.copy()

    @property
    def output_weights(self) -> FloatArray:
        """W with the output thresholds as its last column, shape (n, L2 + 1) (a copy)."""
        return self._w.copy()

    def reset(self) -> None:
        """Start of a run: forget c(t−1), the previous outputs, the stored pass and the momentum; keep the weights."""
        self._previous_position: list[float] | None = None
        self._previous_output = [0.0] * len(self.axis_names)
        self._primed = False
        self._pinned = 0
        self._momentum[:] = 0.0

    def end_run(self) -> None:
        """Nothing: the network learns at every tick."""

    def step(self, sample: CompensatorSample) -> list[float]:
        """Learn from ``sample``'s errors through the previous tick's pass, then the output for this tick.

        Returns a fresh list of corrections [drive units]. A bad sample raises
        :class:`FaultError` before any weight or stored signal changes.
        """
        check_sample(_WHO, sample, self.axis_names)
        if self.fault is None and self._primed and not self.frozen:
            self._learn(sample)
        if self.fault is not None:
            return self._zeros[:]
        return self._forward(sample)

    def _learn(self, sample: CompensatorSample) -> None:
        """One back-propagation step with momentum through the stored pass (module docstring).

        The steps are formed directly: ``_g`` holds −η g, so the outer products are Δw.
        """
        config = self.config
        self._g[:] = self._scaled_deltas(sample, -config.eta)
        slope, hidden_delta = self._slope, self._hidden_delta
        np.multiply(self._o_hidden, self._o_hidden, out=slope)
        np.subtract(1.0, slope, out=slope)
        slope *= 0.5  # f'(q) = (1 − f²)/2
        np.dot(self._w_hidden_t, self._g, out=hidden_delta)
        hidden_delta *= slope
        np.dot(self._g_column, self._o_row, out=self._grad_w)  # outer products as (n,1)(1,m): the cheapest call
        np.dot(self._hidden_delta_column, self._z_row, out=self._grad_v)
        step, theta, momentum = self._gradient, self._theta, self._momentum
        np.copyto(self._backup, theta)
        theta += step
        theta += momentum
        np.multiply(step, config.alpha, out=momentum)
        size = float(np.dot(theta, theta))
        if not size <= config.weight_norm_limit ** 2:
            np.copyto(theta, self._backup)
            self._trip(f"weight norm {math.sqrt(size) if math.isfinite(size) else size} exceeds "
                       f"weight_norm_limit {config.weight_norm_limit} (learning diverged); learning stopped")

    def _scaled_deltas(self, sample: CompensatorSample, factor: float) -> list[float]:
        """``factor`` · g_k, with g_k = δ_k · sign(∂c_k/∂u_k) in the learning law's error unit."""
        config, scale = self.config, self.config.error_scale_per_m
        contour = config.beta * scale * sample.contour_error_m
        theta = sample.angle_rad
        gradient = (-math.sin(theta), math.cos(theta))
        deltas = []
        for k, (error, sign) in enumerate(zip(sample.tracking_error_m, self._signs)):
            delta = -scale * error + (contour * gradient[k] if k < 2 else 0.0)
            deltas.append(factor * delta * sign)
        return deltas

    def _forward(self, sample: CompensatorSample) -> list[float]:
        """The inputs of Eq. 20, the pass through the network, clipped outputs; stores the pass."""
        scale, out_scale = self.config.position_input_scale_per_m, self.config.output_input_scale
        position = sample.position_m
        previous = self._previous_position if self._previous_position is not None else position
        inputs: list[float] = []
        for ref, now, before in zip(sample.ref_position_m, position, previous):
            inputs += (ref * scale, now * scale, before * scale)
        inputs += [u * out_scale for u in self._previous_output]
        self._z[:-1] = inputs
        np.dot(self._v, self._z, out=self._q)
        bipolar_sigmoid(self._q, self._o_hidden)
        np.dot(self._w, self._o, out=self._u)
        output = self._clipped(self._u.tolist())
        self._previous_position = list(position)
        self._previous_output = output
        self._primed = self.fault is None
        return output if self.fault is None else self._zeros[:]

    def _clipped(self, values: list[float]) -> list[float]:
        """Outputs clipped to ±output_limit; the guard counts ticks at the limit and trips on non-finite."""
        limit, pinned = self.config.output_limit, False
        for k, value in enumerate(values):
            if not math.isfinite(value):
                self._trip(f"output {self.axis_names[k]} is {value}; learning stopped")
                return self._zeros[:]
            if value >= limit or value <= -limit:
                values[k], pinned = math.copysign(limit, value), True
        self._pinned = self._pinned + 1 if pinned else 0
        if self._pinned >= self.config.pinned_ticks:
            self._trip(f"output pinned at output_limit {limit} for {self._pinned} ticks; learning stopped")
        return values

    def _trip(self, reason: str) -> None:
        """Stop: zero output from now on, ``fault`` says why."""
        self.fault = f"{_WHO}: {reason}"
        self._primed = False

    def save(self, path: str | Path) -> None:
        """Write V and W (thresholds included) to the ``.npz`` file ``path``."""
        save_state(path, {"input_weights": self._v, "output_weights": self._w})

    def load(self, path: str | Path) -> None:
        """Read V and W from ``path`` (shapes must match this network's); clears the fault and the per-run signals.

        Raises
        ------
        ConfigError
            Naming the file and the problem (see :mod:`.state_file`), or weights whose
            norm exceeds ``weight_norm_limit``; the current weights are kept then.
        """
        arrays = load_state(path, {"input_weights": self._v.shape, "output_weights": self._w.shape},
                            f"{_WHO} weights")
        size = math.hypot(*(float(np.linalg.norm(array)) for array in arrays.values()))
        if size > self.config.weight_norm_limit:
            raise ConfigError(f"{_WHO} weights {str(path)!r} have norm {size:g}, above weight_norm_limit "
                              f"{self.config.weight_norm_limit:g}")
        self._v[:] = arrays["input_weights"]
        self._w[:] = arrays["output_weights"]
        self.fault = None
        self.reset()
