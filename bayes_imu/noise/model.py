"""A noise model: a sum of terms from :mod:`bayes_imu.noise` at one sample period."""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, ModelError
from ._base import DERIVED_PARAMETERS, KALIBR_ROLES, ROLES, SELECTION_ROLES, TAIL_KINDS, Term
from .bias_instability import BIAS_INSTABILITY
from .filtered_white import FILTERED_WHITE
from .gauss_markov import GAUSS_MARKOV, GAUSS_MARKOV_2, HF_CORRELATED
from .quantization import QUANTIZATION
from .ramp import RAMP
from .random_walk import RANDOM_WALK
from .vibration import VIBRATION
from .white import WHITE

__all__ = ["REGISTRY", "check_declarations", "TERMS", "TERM_PARAMETERS", "PARAMETER_UNITS",
           "WORST_AXIS", "PARAMETER_LABELS", "NoiseModel", "m_array"]



def _registered(*terms):
    """``name -> term`` after checking each term's declarations (:func:`check_declarations`)."""
    out = {}
    for term in terms:
        check_declarations(term, known=tuple(out))
        out[term.name] = term
    return out


def check_declarations(term, *, known=None):
    """:class:`~bayes_imu.errors.ModelError` unless ``term`` declares what the pipeline looks up:
    a role, selection roles, a Kalibr role and a covariance-tail kind from their allowed sets,
    units for every parameter, and required terms among ``known`` (the registry by default)."""
    known = tuple(REGISTRY) if known is None else known
    problems = []
    if not isinstance(term, Term):
        raise ModelError(f"{term!r} is not a Term")
    if term.role not in ROLES:
        problems.append(f"role {term.role!r} not in {ROLES}")
    if not term.selection or not set(term.selection) <= set(SELECTION_ROLES):
        problems.append(f"selection {term.selection!r}: expected roles from {SELECTION_ROLES}")
    if term.kalibr not in KALIBR_ROLES:
        problems.append(f"kalibr {term.kalibr!r} not in {KALIBR_ROLES}")
    if term.tail_kind not in TAIL_KINDS:
        problems.append(f"covariance tail kind {term.tail_kind!r} not in {TAIL_KINDS}")
    if set(term.units) != set(term.parameters) or not term.parameters:
        problems.append(f"units {sorted(term.units)} do not match parameters {term.parameters}")
    odd = [p for p in term.worst_axis if p not in term.parameters + DERIVED_PARAMETERS]
    if odd:
        problems.append(f"worst_axis names {odd}, not its parameters or {DERIVED_PARAMETERS}")
    if not isinstance(term.exchangeable, str) or (term.exchangeable and len(term.parameters) != 2):
        problems.append(f"exchangeable {term.exchangeable!r}: expected a group name for a term "
                        "of two parameters (variance, time constant), or ''")
    labels = term.parameter_labels or {}
    if not set(labels) <= set(term.parameters):
        problems.append(f"parameter_labels {sorted(labels)} name no parameter of {term.parameters}")
    missing = [t for t in term.requires if t not in known]
    if missing:
        problems.append(f"requires unknown terms {missing}")
    if problems:
        raise ModelError(f"term {term.name!r}: " + "; ".join(problems))
    return term


#: every term, in canonical order (Gauss-Markov kinds from fastest to slowest)
REGISTRY = _registered(WHITE, QUANTIZATION, FILTERED_WHITE, HF_CORRELATED, BIAS_INSTABILITY,
                       GAUSS_MARKOV, GAUSS_MARKOV_2, RANDOM_WALK, RAMP, VIBRATION)
TERMS = tuple(REGISTRY)
TERM_PARAMETERS = {name: t.parameters for name, t in REGISTRY.items()}
#: unit of each parameter, given the unit ``u`` of the rate samples
PARAMETER_UNITS = {p: u for t in REGISTRY.values() for p, u in t.units.items()}
PARAMETER_UNITS["noise_density"] = "{u}/sqrt(Hz)"
PARAMETER_UNITS["white_noise_density"] = "{u}/sqrt(Hz)"
#: parameters a several-column summary reports as the worst axis, in registry order
#: (:attr:`Term.worst_axis`)
WORST_AXIS = tuple(p for t in REGISTRY.values() for p in t.worst_axis)
#: what figures and tables call each parameter (:meth:`Term.parameter_label`) and the derived
#: noise density
PARAMETER_LABELS = {p: t.parameter_label(p) for t in REGISTRY.values() for p in t.parameters}
PARAMETER_LABELS["noise_density"] = "noise density"


def m_array(m):
    """Validated cluster sizes as floats."""
    m = np.asarray(m)
    if m.ndim != 1 or m.size == 0 or not np.all(m >= 1) or not np.all(m == np.round(m)):
        raise InputError(
            f"cluster sizes m: expected a non-empty 1-D array of integers >= 1, got {m!r}"
        )
    return m.astype(float)


@dataclass(frozen=True)
class NoiseModel:
    """A sum of noise terms for rate samples at period ``dt``.

    Attributes
    ----------
    terms : tuple of str
        Term names, a subset of :data:`TERMS` (kept in canonical order).
    dt : float
        Sample period [s].
    """

    terms: tuple
    dt: float

    def __post_init__(self):
        unknown = [t for t in self.terms if t not in REGISTRY]
        if unknown or not self.terms or len(set(self.terms)) != len(self.terms):
            raise InputError(
                f"model terms {self.terms!r}: expected distinct names from {', '.join(TERMS)}"
            )
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise InputError(f"dt={self.dt!r}: expected a positive sample period in seconds")
        for name in self.terms:
            missing = [t for t in REGISTRY[name].requires if t not in self.terms]
            if missing:
                raise InputError(f"model terms: {name} ({REGISTRY[name].label}) needs "
                                 f"{', '.join(missing)}")
        object.__setattr__(self, "terms", tuple(t for t in TERMS if t in self.terms))

    @property
    def components(self):
        """The :class:`~bayes_imu.noise.Term` objects, in order."""
        return tuple(REGISTRY[t] for t in self.terms)

    @property
    def parameter_names(self):
        """Parameter names in sampling order."""
        return tuple(p for t in self.components for p in t.parameters)

    @property
    def ordered(self):
        """Indices of the Gauss-Markov time constants, fastest first (they must increase)."""
        names = self.parameter_names
        return tuple(
            names.index(t.parameters[1])
            for t in self.components
            if hasattr(t, "time_constant_name")
        )

    def unpack(self, theta):
        """Split an array ``(..., n_par)`` (extra trailing columns ignored) into a dict name ->
        ``(...)``."""
        theta = np.asarray(theta, float)
        return {name: theta[..., i] for i, name in enumerate(self.parameter_names)}

    def term_avar(self, term, m, params):
        """Allan variance of one term, ``(..., n_tau)``."""
        params = params if isinstance(params, dict) else self.unpack(params)
        return REGISTRY[term].avar(
            m_array(m), {k: np.asarray(v, float) for k, v in params.items()}, self.dt
        )

    def avar(self, m, params):
        """Model Allan variance ``(..., n_tau)`` for parameters given as a dict or ``(...,
        n_par)``."""
        return self.avar_evaluator(m)(params)

    def avar_evaluator(self, m):
        """A function ``params -> (..., n_tau)`` for fixed cluster sizes ``m`` (validated once;
        picklable)."""
        return AvarEvaluator(self, m_array(m))

    def structure_function(self, k, params):
        """Phase structure function of the sum (scalar parameters), see :mod:`bayes_imu.noise`."""
        return sum(t.structure(k, params, self.dt) for t in self.components)

    def short_term_variance(self, params):
        """Per-sample variance of the white noise the short-term terms amount to at ``tau >> T_hf``.

        White noise plus the white equivalent of the filtered-white and high-frequency
        correlated terms: the
        ``noise_density`` users compare with a datasheet's ARW / VRW or ADEV(1 s).
        """
        params = params if isinstance(params, dict) else self.unpack(params)
        total = np.asarray(params.get("noise_variance", 0.0), float)
        for term in self.components:
            if term.role == "short_term" and hasattr(term, "white_equivalent"):
                total = total + term.white_equivalent(params, self.dt)
        return total


class AvarEvaluator:
    """``params -> (..., n_tau)``: the Allan variance of ``model`` at fixed cluster sizes ``mf``
    (:meth:`NoiseModel.avar_evaluator`); a class, not a closure, so that a fit can be pickled
    (the outputs are written by another process, :mod:`bayes_imu.report.worker`).

    The terms with an :attr:`~bayes_imu.noise.Term.avar_power` (white noise, a random walk, ...:
    ``p**k`` times a curve of ``m``) are evaluated together as one sum of products of their
    parameters' powers with their curves at unit parameter, computed once here; the others each
    alone, or one call per :attr:`~bayes_imu.noise.Term.avar_group`. The sum is the model's to
    rounding (tested against the terms' own sum), and each row's the same bits in any batch
    (tested); a likelihood call of 16 walkers spends up to a quarter less time here
    (``docs/speed_under_load.md``, "Twelfth session").
    """

    __slots__ = ("model", "mf", "_names", "_components", "_plan", "_linear", "_others")

    def __init__(self, model, mf):
        self.model = model
        self.mf = mf
        self._names = model.parameter_names  # the model is frozen: looked up once, not per call
        self._components = model.components
        linear = [t for t in model.components if t.avar_power is not None]
        self._linear = None
        if linear:
            # squared parameters first: squared in place as one slice of the gathered columns
            linear.sort(key=lambda t: t.avar_power != 2)
            names = tuple(t.parameters[0] for t in linear)
            curves = np.stack([np.broadcast_to(t.avar(mf, {t.parameters[0]: np.asarray(1.0)},
                                                      model.dt), mf.shape) for t in linear])
            powers = np.array([t.avar_power for t in linear], float)
            n_squared = int(np.sum(powers == 2))
            # powers other than 1 and 2 (none among the built-in terms), raised one by one
            other = powers[n_squared:] if np.any(powers[n_squared:] != 1.0) else None
            self._linear = (names, np.array([self._names.index(n) for n in names]), n_squared,
                            other, np.ascontiguousarray(curves))
        # the terms of one avar_group evaluated in one call (Term.avar_many), the rest alone
        groups = {}
        for i, term in enumerate(model.components):
            if term.avar_power is not None:
                continue
            key = term.avar_group if term.avar_group is not None else ("alone", i)
            groups.setdefault(key, []).append(i)
        self._plan = tuple((tuple(index), tuple(model.components[j] for j in index[1:]))
                           for index in groups.values())
        # the parameters of the terms evaluated one by one (the others' are gathered by column)
        alone = {p for t in model.components if t.avar_power is None for p in t.parameters}
        self._others = tuple((i, name) for i, name in enumerate(self._names) if name in alone)

    def __getstate__(self):
        return self.model, self.mf

    def __setstate__(self, state):
        self.__init__(*state)

    def __call__(self, params):
        mf, dt = self.mf, self.model.dt
        out = None
        if isinstance(params, dict):
            params = {k: np.asarray(params[k], float) for k in self._names}
            if self._linear is not None:
                names = self._linear[0]
                amplitudes = np.stack(np.broadcast_arrays(*(params[n] for n in names)), axis=-1)
                out = self._linear_part(amplitudes)
        else:
            theta = np.asarray(params, float)
            # only the parameters of the terms evaluated one by one
            params = {name: theta[..., i] for i, name in self._others}
            if self._linear is not None:
                out = self._linear_part(theta[..., self._linear[1]])
        components = self._components
        owned = out is not None  # the linear part is a new array: added into in place
        for index, others in self._plan:
            if others:
                parts = components[index[0]].avar_many(others, mf, params, dt)
            else:
                parts = (components[index[0]].avar(mf, params, dt),)
            for part in parts:
                if out is None:
                    out = part  # a term's own array: not changed here
                elif owned and out.shape == np.shape(part):
                    out += part
                else:
                    out = out + part
                    owned = True
        return out

    def _linear_part(self, amplitudes):
        """The terms with an ``avar_power``: ``amplitudes`` ``(..., k)`` (their parameters, a copy
        this may change) raised to their powers, times their curves ``(k, n_tau)``, summed."""
        _, _, n_squared, other, curves = self._linear
        if n_squared:
            head = amplitudes[..., :n_squared]
            head *= head
        if other is not None:
            amplitudes[..., n_squared:] **= other
        if curves.shape[0] == 1:  # one such term (white noise alone): a product
            return amplitudes * curves[0]
        # numpy's own sum of products, not a matrix product: a walker's value is then the same
        # bits whichever batch it is evaluated in (BLAS rounds a row of a matrix product as it
        # blocks the matrix; tests/test_models.py)
        return np.einsum("...k,kn->...n", amplitudes, curves)
