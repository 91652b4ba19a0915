"""Joint maximum-likelihood fit of every parameter at once.

The paper estimates the parameters in four separate searches (III-A…D), each
blind to the others' errors.  Here all of them — spin (eq. 2), tilt, R, gains
and offsets — are fitted together by Levenberg–Marquardt with the analytic
Jacobian of :mod:`wheelcal.model.forward`, which attains the Cramér–Rao bound:

1. start from the closed-form guess of :mod:`wheelcal.estimate.joint.initial` (the
   data and the radius only — never the truth);
2. least squares with per-axis weights from a first-difference noise estimate
   (on a decimated copy of ~3 000 samples: it only needs to get within a few σ;
   then, on a long or fast recording, stages on N/100 and N/10 of the N samples
   (those above 6 000), so that stage 2 starts ≲ 10 σ away and its noise model
   is not fitted to a start's misfit);
3. estimate the noise model (AR colour per axis, cross-axis correlation) from
   full residual and refit the whitened (generalised least squares) problem on
   every sample, from the canonical twin (the smaller offset: the decimated fit
   already tells the twins apart).  From 5–10 σ away this takes one pass with
   the Jacobian (H and g at the start), a Gauss–Newton step judged by the
   gradient alone (the start's H serving), and a last step (< 0.3 σ) confirmed
   by the cost alone (:mod:`wheelcal.estimate.joint.levenberg_marquardt`), whose
   residual is the result's;
4. choose the discrete twin with the smaller offset, and compute the covariance
   from the Fisher information, the systematic budget and the identifiability
   verdict there.  (Stage 2 moves the estimate by a small fraction of σ, so the
   noise model estimated before it is the noise model at the optimum.)

Geometry modes (paper II-C): ``radius`` — r known, α fitted (the paper's choice);
``tilt`` — α known, r fitted; ``vertical`` — α = 90° (a spirit level), r fitted;
``free`` — α and r both fitted (the field fit's turns measure α).  A wheel
rolling on the ground is the field fit's (:mod:`wheelcal.estimate.field`), which
runs this fit in passes with the rolling effect (:mod:`wheelcal.model.rolling`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint.columns import difference_stds
from wheelcal.estimate.joint.decimation import thinning_stride
from wheelcal.estimate.joint.gyro_equations import accumulate_gyro, combined, gyro_prediction
from wheelcal.estimate.joint.gyro_rests import GyroRests
from wheelcal.estimate.joint.identifiability import Identifiability, check_identifiability
from wheelcal.estimate.joint.information import covariance_from_fisher
from wheelcal.estimate.joint.initial import InitialGuess, initial_guess
from wheelcal.estimate.joint.levenberg_marquardt import LMOutcome, levenberg_marquardt
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import (
    CHUNK_SAMPLES,
    NormalEquations,
    accumulate,
    accumulate_fitting_noise,
    effect_priors,
    gradient_pass,
    residual_of,
    whitened_cost,
)
from wheelcal.estimate.joint.reporting import report_transform, transform_covariance
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.estimate.joint.systematic import (
    DEFAULT_CLOCK_STD_PPM,
    DEFAULT_GRAVITY_STD_MPS2,
    GIVEN_GRAVITY_STD_MPS2,
    SystematicBudget,
    nuisance_columns,
    nuisance_extra,
    systematic_budget,
)
from wheelcal.estimate.joint.twins import TwinChoice, choose_twin, twin_of
from wheelcal.model import (
    G_SENSITIVITY_PRIOR_DPS_PER_G,
    CalibrationParams,
    EvaluatedModel,
    GyroReading,
    ModelOutput,
    ParameterLayout,
    SpinSpline,
    bench_force,
    evaluate,
    wheel_kinematics,
)
from wheelcal.recording import Recording, RecordingError, SessionInfo

GEOMETRY_MODES = ("radius", "tilt", "vertical", "free")
#: Stage 1 runs on about this many samples (decimated); stage 2 uses all of them.
_STAGE1_SAMPLES = 3000
#: Stage 2's last Gauss–Newton step is taken without a Jacobian when below √this σ.
_FINAL_STEP_TOL = 0.1
#: The same for stage 1 (it only needs to get close: stage 2 iterates from there).
_STAGE1_FINAL_STEP_TOL = 10.0
#: Between stage 1 and all N samples, stages on N/10, N/100, … samples (those above
#: ``_LADDER_MIN_SAMPLES``): a decimated stage on M samples with white weights ends
#: ~k·√(N/M) σ of the whole from its optimum (k ≈ 1–3, more for coloured noise), and
#: stage 2's one Gauss–Newton step lands within 0.3 σ from ~10 σ, not from 20.
_LADDER_STEP = 10
_LADDER_MIN_SAMPLES = 2 * _STAGE1_SAMPLES


@dataclass(frozen=True)
class JointFit:
    """Configuration of the joint ML fit; :meth:`fit` returns a frozen result.

    Parameters
    ----------
    spin_degree:
        Degree of the ω(t) polynomial (3 = the paper's cubic).
    geometry:
        ``"radius"`` (default), ``"tilt"``, ``"vertical"`` or ``"free"`` (α and r
        both fitted: only with an effect that
        measures the tilt otherwise, :mod:`wheelcal.estimate.field`; the start at α = 90°);
        see the module doc.
    known_tilt_deg:
        The measured tilt in ``"tilt"`` mode.
    tilt_std_deg:
        Uncertainty of the known tilt (levelling), for the systematic budget.
    coloured_noise:
        Model the residual as AR noise (True) or as white noise per axis.
    max_ar_order:
        Largest AR order tried (chosen by AIC).
    clock_std_ppm, gravity_std_mps2:
        Systematic-budget inputs; ``gravity_std_mps2=None`` uses 0.02 m/s² when the
        session does not give local gravity and 1e-4 m/s² when it does.
    effects:
        Model extensions to fit (:mod:`wheelcal.model.effects`).  The discrete
        twin is chosen on the paper's model first (effects such as a nonlinearity
        break the twin symmetry), then the effects are fitted from zero.
    use_gyro:
        Fit the recording's gyroscope too (:class:`~wheelcal.model.effects.GyroReading`:
        ω_meas = w ω + b), as a second, independent stream of the likelihood.
    spline_spacing_s:
        Let the wheel angle follow any motion: the cubic plus a cubic B-spline
        correction with knots this far apart (:class:`~wheelcal.model.effects.SpinSpline`).
        ``None`` keeps the paper's cubic.
    """

    spin_degree: int = 3
    geometry: str = "radius"
    known_tilt_deg: float | None = None
    tilt_std_deg: float = 0.5
    coloured_noise: bool = True
    max_ar_order: int = 10
    max_iterations: int = 100
    clock_std_ppm: float = DEFAULT_CLOCK_STD_PPM
    gravity_std_mps2: float | None = None
    effects: tuple = ()
    use_gyro: bool = False
    spline_spacing_s: float | None = None
    #: σ of the prior on the gyro's sensitivity to linear acceleration, °/s/g
    #: (:class:`~wheelcal.model.effects.GyroReading`; None: no prior).
    gyro_g_prior_dps_per_g: float | None = G_SENSITIVITY_PRIOR_DPS_PER_G
    #: The gyro's static readings at the rests around the window (:mod:`.gyro_rests`),
    #: fitted with its stream (None: none).
    gyro_rests: GyroRests | None = None

    def __post_init__(self) -> None:
        if self.spline_spacing_s is not None and not self.spline_spacing_s > 0:
            raise ValueError("spline_spacing_s must be positive")
        if self.geometry not in GEOMETRY_MODES:
            raise ValueError(f"geometry must be one of {GEOMETRY_MODES}, got {self.geometry!r}")
        if self.geometry == "tilt" and self.known_tilt_deg is None:
            raise ValueError("geometry 'tilt' needs known_tilt_deg")
        if self.known_tilt_deg is not None and not 0.0 <= self.known_tilt_deg <= 90.0:
            raise ValueError("known_tilt_deg must lie in [0, 90]")

    @property
    def layout(self) -> ParameterLayout:
        """Free parameters for this configuration (without the window's motion effects)."""
        return ParameterLayout(
            spin_degree=self.spin_degree,
            fit_tilt=self.geometry in ("radius", "free"),
            fit_radius=self.geometry in ("tilt", "vertical", "free"),
            effects=tuple(self.effects),
        )

    def _spline(self, tc: np.ndarray) -> SpinSpline | None:
        if self.spline_spacing_s is None:
            return None
        return SpinSpline(float(tc[0]), float(tc[-1]), self.spline_spacing_s)

    def layout_for(
        self, recording: Recording, frame: tuple[float, float] | None = None
    ) -> ParameterLayout:
        """Free parameters for this configuration and window (spline, gyro included).

        ``frame`` (start, end in recording time) is the window that sets the time
        origin and the spline's knots; default: the recording's first and last sample.
        """
        start, end = frame or (float(recording.time_s[0]), float(recording.time_s[-1]))
        centre = 0.5 * (start + end)
        spline = self._spline(np.array([start - centre, end - centre]))
        # The spline corrects the base motion itself, so it comes first: a spin effect that
        # follows (an imbalance's wobble, ∝ 1/ω at the angle ϑ) acts on the corrected ϑ, ω —
        # after it, the wobble of a pushed wheel would turn at the cubic's angle alone.
        first = () if spline is None else (spline,)
        last = (self.gyro_reading(),) if self.use_gyro else ()
        return dataclasses.replace(self.layout, effects=first + tuple(self.effects) + last)

    def gyro_reading(self) -> GyroReading:
        """The gyroscope's reading with this configuration's prior on G."""
        return GyroReading(g_sensitivity=True, g_prior_dps_per_g=self.gyro_g_prior_dps_per_g)

    def rests_of(self, rests) -> GyroRests | None:
        """The gyro's readings at ``rests`` (RestSegments) for this fit's reading, or None."""
        return GyroRests.of(rests, self.gyro_reading().g_prior_std_radps_per_mps2)

    def _fixed_tilt_rad(self) -> float | None:
        if self.geometry in ("vertical", "free"):
            return np.pi / 2
        if self.geometry == "tilt":
            return float(np.deg2rad(self.known_tilt_deg))
        return None

    def _checked_info(self, recording: Recording):
        info = recording.info
        if self.geometry == "radius" and info.radius_m is None:
            raise RecordingError(
                f"{recording.source}: the radius (sensor distance from the axle) is needed: "
                "give --radius or radius_m in the wheelcal.session metadata"
            )
        return info

    def start(self, recording: Recording, fastest_radps: float | None = None) -> InitialGuess:
        """The closed-form starting point (:mod:`wheelcal.estimate.joint.initial`) for a window.

        ``fastest_radps``: the wheel's fastest |ω| in the window, when the window
        search has measured it (it spares the start a spectrum of every sample).
        """
        info = self._checked_info(recording)
        t = recording.time_s
        tc = t - 0.5 * (t[0] + t[-1])
        gyro_t = gyro = rate = None
        if self.use_gyro:
            gyro_t, gyro = gyro_samples(recording, tc)
            _, vecs = np.linalg.eigh(gyro.T @ gyro)
            rate = np.interp(tc, gyro_t, gyro @ vecs[:, -1])  # ω up to sign, scale, bias
        guess = initial_guess(
            tc,
            recording.accel_mps2,
            info.gravity_or_standard_mps2,
            radius_m=info.radius_m if self.geometry == "radius" else None,
            tilt_rad=self._fixed_tilt_rad(),
            spin_degree=self.spin_degree,
            spline=self._spline(tc),
            omega_radps=rate,
            fastest_radps=fastest_radps,
        )
        if not self.use_gyro:
            return guess
        params = with_gyro_start(guess.params, self.layout_for(recording), gyro_t, gyro)
        return dataclasses.replace(guess, params=params)

    def fit(
        self,
        recording: Recording,
        initial: CalibrationParams | None = None,
        guess: InitialGuess | None = None,
        frame: tuple[float, float] | None = None,
    ) -> CalibrationResult:
        """Calibrate one recording (already cut to its free-spin window).

        ``initial`` starts from given parameters; ``guess`` reuses a
        :meth:`start` already computed for this window.  ``frame`` (start,
        end in recording time) keeps the time origin and the spline's knots of a
        larger window when refitting a subset of it from its ``initial``.
        """
        return self._fit(recording, initial, guess, frame)[0]

    def fit_evaluated(
        self, recording: Recording, guess: InitialGuess | None = None
    ) -> tuple[CalibrationResult, EvaluatedModel | None]:
        """:meth:`fit` of a window from its start, and the model as its last pass evaluated it.

        The evaluation (:class:`~wheelcal.model.forward.EvaluatedModel`) is there
        for a window of one chunk and the paper's model (None otherwise): a check
        at the result (the motion check) forms its Jacobian from it.
        """
        return self._fit(recording, None, guess, None)

    def _fit(
        self,
        recording: Recording,
        initial: CalibrationParams | None,
        guess: InitialGuess | None,
        frame: tuple[float, float] | None,
    ) -> tuple[CalibrationResult, EvaluatedModel | None]:
        """The stages of the module doc, in order; the result and the last evaluation."""
        window = self._window(recording, frame)
        initial, notes = self._initial(recording, initial, guess)
        stage1 = self._stage1(window, initial)
        stage2 = self._stage2(window, stage1.params)
        end = self._at_twin(window, stage2)
        result = self._result(window, stage2, end, notes)
        last = stage2.last_residual
        return result, last.evaluated_at(end.params) if last is not None else None

    def _window(self, recording: Recording, frame: tuple[float, float] | None) -> _Window:
        """The window's samples as the stages use them (times centred on ``frame``)."""
        info = self._checked_info(recording)
        t = recording.time_s
        frame = frame or (float(t[0]), float(t[-1]))
        centre = 0.5 * (frame[0] + frame[1])
        tc = t - centre
        layout = self.layout_for(recording, frame)
        gyro_t, gyro = gyro_samples(recording, tc) if self.use_gyro else (None, None)
        return _Window(recording, info, centre, tc, recording.accel_mps2, layout, gyro_t, gyro)

    def _initial(
        self, recording: Recording, initial: CalibrationParams | None, guess: InitialGuess | None
    ) -> tuple[CalibrationParams, tuple[str, ...]]:
        """Where the fit starts, and the start's notes."""
        if initial is None and self.effects:
            # Settle the twin on the paper's model, then free the effects from zero.
            initial = dataclasses.replace(self, effects=()).fit(recording, guess=guess).params
        if initial is None:
            guess = guess or self.start(recording)
            return guess.params, guess.notes
        return initial, ()

    def _stage1(self, w: _Window, initial: CalibrationParams) -> LMOutcome:
        """Stage 1: least squares on a decimated copy (it only needs to get close).

        Per-axis weights from first differences; never below 16 samples per turn
        at the fastest rate (no aliasing).  Then, without a gyro, the ladder of
        decimations toward all samples (a long, fast recording).
        """
        tc, v, layout, gyro = w.tc, w.v, w.layout, w.gyro
        omega_max = float(np.max(np.abs(initial.spin.omega_at(tc[[0, tc.size // 2, -1]]))))
        stride = thinning_stride(tc.size, _STAGE1_SAMPLES, w.recording.rate_hz, omega_max)
        std0 = np.maximum(difference_stds(v) / np.sqrt(2), 1e-6)
        white0 = NoiseModel.white(std0)
        gyro1 = None
        if gyro is not None:
            gyro_std0 = np.maximum(np.std(np.diff(gyro, axis=0), axis=0) / np.sqrt(2), 1e-9)
            gyro1 = (w.gyro_t[::stride], gyro[::stride], NoiseModel.white(gyro_std0))
        out = levenberg_marquardt(
            _residual_fn(
                tc[::stride], v[::stride], layout, white0, gyro=gyro1, gyro_rests=self.gyro_rests
            ),
            initial,
            layout,
            self.max_iterations,
            tol=1e-2,  # close is enough: < 0.1 σ of this decimated problem
            # The gyro-aided start (rate measured, phase demodulated) is close and the
            # spline enters linearly: Gauss–Newton steps (2 instead of 7 on a clean spin).
            initial_damping=1e-7 if gyro is not None else 1e-3,
            # Its last step (< 3 σ of this problem) needs no Jacobian: the cost confirms it.
            final_step_tol=_STAGE1_FINAL_STEP_TOL,
            # The step's end judged by its gradient, the start's Hessian serving: the
            # paper's model only.  Effects are freed here from zero, where the Hessian
            # is not the end's (a warm-up's τ has no column while its amplitude is 0).
            gradient_fn=None
            if gyro is not None or self.effects
            else _gradient_fn(tc[::stride], v[::stride], layout, white0),
        )
        if gyro is None:  # a ladder of decimations toward all samples (a long, fast recording)
            out = self._ladder_stages(w, out, stride, omega_max, white0)
        return out

    def _ladder_stages(
        self, w: _Window, out: LMOutcome, stride: int, omega_max: float, white0: NoiseModel
    ) -> LMOutcome:
        """Stages on N/100, N/10 … of the N samples after stage 1 (:func:`_ladder`)."""
        tc, v, layout = w.tc, w.v, w.layout
        for target in _ladder(tc.size):
            finer = thinning_stride(tc.size, target, w.recording.rate_hz, omega_max)
            if finer >= stride:
                continue
            stride = finer
            out = levenberg_marquardt(
                _residual_fn(tc[::stride], v[::stride], layout, white0),
                out.params,
                layout,
                self.max_iterations,
                tol=1e-2,
                initial_damping=1e-9,  # warm start: Gauss–Newton steps
                jacobian_on_trial=True,
                final_step_tol=_STAGE1_FINAL_STEP_TOL,
                gradient_fn=_gradient_fn(tc[::stride], v[::stride], layout, white0),
            )
        return out

    def _stage2(self, w: _Window, start: CalibrationParams) -> _Stage2:
        """Stage 2: noise model from the full residual, whitened refit on all samples.

        The accumulations carry the sensitivities to the fixed quantities as
        extra columns, so the last one also gives the systematic budget.
        """
        tc, v, layout, gyro = w.tc, w.v, w.layout, w.gyro
        if not self.effects:
            # The canonical twin: the twins' offsets differ by far more than σ, so the
            # decimated fit already tells them apart, and the end point is then
            # canonical too (no second Jacobian pass for the other twin in stage 3).
            # The gyro's reading and the spline mirror with the twin (twins.py).
            start = choose_twin(start).chosen
        normal0 = None
        if gyro is None and (tc.size <= CHUNK_SAMPLES or not self.effects):
            normal0, noise = accumulate_fitting_noise(
                start, tc, v, layout, self._noise_model, nuisance_extra(nuisance_columns(layout))
            )
        else:
            noise = self._noise_model(residual_of(start, tc, v, layout))
        gyro2 = gyro_noise = None
        if gyro is not None:
            gyro_noise = self._noise_model(gyro - gyro_prediction(start, w.gyro_t, layout))
            gyro2 = (w.gyro_t, gyro, gyro_noise)
        normal_fn = _residual_fn(
            tc, v, layout, noise, nuisance_columns(layout), gyro=gyro2, gyro_rests=self.gyro_rests
        )
        last_residual = _LastResidual(normal_fn, tc, v, layout, noise) if gyro is None else None
        out = levenberg_marquardt(
            last_residual or normal_fn,
            start,
            layout,
            self.max_iterations,
            tol=1e-3,  # stop when the next step would be < 0.03 σ
            initial_damping=1e-9,  # warm start: Gauss–Newton steps
            jacobian_on_trial=True,  # ... which are accepted: one pass per step
            # The last step (< 0.3 σ) needs no Jacobian: the cost confirms it.
            final_step_tol=_FINAL_STEP_TOL,
            # The step from the start lands within a small fraction of σ: there the
            # gradient (the whitening applied to the residual, not to J) and the
            # start's Hessian decide the last step, and serve as the Fisher information.
            gradient_fn=last_residual.gradient if last_residual is not None else None,
            normal0=normal0,
        )
        return _Stage2(out, noise, gyro2, gyro_noise, last_residual)

    def _at_twin(self, w: _Window, stage2: _Stage2) -> _AtTwin:
        """Stage 3: the canonical twin, and the Fisher information there.

        The normal equations carry the cross terms with the quantities held
        fixed (for the systematic budget).
        """
        out = stage2.out
        if self.effects:  # the twin was chosen on the base model (see `effects`)
            twin = TwinChoice(out.params, twin_of(out.params), ambiguous=False)
        else:
            twin = choose_twin(out.params)
        params = twin.chosen
        tc, v, layout = w.tc, w.v, w.layout
        normal = out.normal
        if not _same_point(params, out.params):  # the other twin: new Jacobian
            nuisances = nuisance_columns(layout)
            normal = _residual_fn(
                tc, v, layout, stage2.noise, nuisances, gyro=stage2.gyro, gyro_rests=self.gyro_rests
            )(params, True)
        size = layout.size
        cov_x = covariance_from_fisher(normal.hessian[:size, :size])
        names, values, g = report_transform(params, layout)
        cov = transform_covariance(g, cov_x)
        last = stage2.last_residual
        residual = last.at(params) if last is not None else None
        if residual is None:
            residual = residual_of(params, tc, v, layout)
        return _AtTwin(twin, normal, names, values, g, cov, residual)

    def _budget(self, w: _Window, end: _AtTwin) -> SystematicBudget:
        """The systematic budget at the result (the quantities held fixed)."""
        gravity_std = self.gravity_std_mps2
        if gravity_std is None:
            gravity_std = (
                DEFAULT_GRAVITY_STD_MPS2 if w.info.gravity_mps2 is None else GIVEN_GRAVITY_STD_MPS2
            )
        return systematic_budget(
            end.params,
            w.layout,
            end.normal.hessian,
            nuisance_columns(w.layout),
            end.jacobian,
            end.names,
            radius_std_m=w.info.radius_std_m,
            gravity_std_mps2=gravity_std,
            clock_std_ppm=self.clock_std_ppm,
            tilt_std_deg=self.tilt_std_deg,
        )

    def _warnings(
        self, w: _Window, out: LMOutcome, twin: TwinChoice, ident: Identifiability
    ) -> tuple[str, ...]:
        """The fit's warnings: identifiability, convergence, twin, geometry."""
        warnings = list(ident.warnings)
        if not out.converged:
            warnings.append(f"the fit did not converge ({out.message})")
        if twin.warning and self.geometry != "vertical":
            warnings.append(twin.warning)
        if self.geometry != "radius" and w.info.gravity_mps2 is None:
            gravity = w.info.gravity_or_standard_mps2
            warnings.append(
                f"{self.geometry} mode without local gravity: the gains scale with the assumed "
                f"g ({gravity:.5f} m/s²) one for one — give gravity_mps2 for gains better "
                "than ~0.2 %"
            )
        if self.geometry == "vertical":
            warnings.append(
                "vertical wheel: the wheel axis has no upward side, so R is reported for the "
                "positive spin direction (gains and offsets are unaffected)"
            )
        return tuple(warnings)

    def _result(
        self, w: _Window, stage2: _Stage2, end: _AtTwin, notes: tuple[str, ...]
    ) -> CalibrationResult:
        """The frozen result at the chosen twin."""
        out = stage2.out
        budget = self._budget(w, end)
        ident = check_identifiability(end.params, w.tc, end.names, np.sqrt(np.diag(end.covariance)))
        # χ² at the result: the cost the iterations ended on (the twin's own if chosen).
        chi2 = out.cost if end.normal is out.normal else end.normal.cost
        return CalibrationResult(
            # The window's samples and facts.
            layout=w.layout,
            time_s=w.recording.time_s,
            centre_s=float(w.centre),
            epoch_unix_ns=w.recording.epoch_unix_ns,
            info=w.info,
            source=w.recording.source,
            topic=w.recording.topic,
            notes=tuple(notes) + w.recording.notes,
            # Stage 2: the noise models, how the iterations ended, χ² (N entries).
            noise=stage2.noise,
            gyro_noise=stage2.gyro_noise,
            gyro_rests=self.gyro_rests if w.gyro is not None else None,
            converged=out.converged,
            iterations=out.iterations,
            chi2=float(chi2),
            entries=int(end.normal.entries),
            # Stage 3: at the chosen twin.
            params=end.params,
            twin=end.twin,
            names=end.names,
            values=end.values,
            covariance=end.covariance,
            residual_mps2=end.residual,
            systematic=budget,
            identifiability=ident,
            warnings=self._warnings(w, out, end.twin, ident),
        )

    def _noise_model(self, residual: np.ndarray) -> NoiseModel:
        if self.coloured_noise:
            return NoiseModel.estimate(residual, self.max_ar_order)
        return NoiseModel.white(np.std(residual, axis=0))


@dataclass(frozen=True, eq=False)
class _Window:
    """A window's samples as the fit's stages use them."""

    recording: Recording
    info: SessionInfo
    centre: float  # the frame's middle, recording time
    tc: np.ndarray  # sample times − centre
    v: np.ndarray  # accelerometer samples (N, 3)
    layout: ParameterLayout
    gyro_t: np.ndarray | None  # centred times of the usable gyro rows
    gyro: np.ndarray | None  # those rows


@dataclass(frozen=True, eq=False)
class _Stage2:
    """Where stage 2 ended, and the noise models it whitened with."""

    out: LMOutcome
    noise: NoiseModel
    gyro: tuple | None  # (times, samples, noise model) of the gyro stream
    gyro_noise: NoiseModel | None
    last_residual: _LastResidual | None


@dataclass(frozen=True, eq=False)
class _AtTwin:
    """Stage 3: the chosen twin and what the result reports there."""

    twin: TwinChoice
    normal: NormalEquations  # at the chosen twin (nuisance columns last)
    names: tuple[str, ...]
    values: np.ndarray
    jacobian: np.ndarray  # ∂(reported)/∂(optimiser vector)
    covariance: np.ndarray  # of the reported values
    residual: np.ndarray  # data − model (N, 3)

    @property
    def params(self) -> CalibrationParams:
        """The chosen twin's parameters."""
        return self.twin.chosen


#: A gradient pass's Jacobian (with effects) is kept for the Hessian at the same point on
#: windows of up to this many samples: two chunks, ~70 MB for 45 columns (a 90 s robot
#: drive at 400 Hz: one evaluation of the model less per step).
KEEP_JACOBIAN_SAMPLES = 2 * CHUNK_SAMPLES


class _LastResidual:
    """``normal_fn`` whose cost-only and gradient evaluations keep their residual.

    The LM's last point is reached by a gradient pass (a step below the
    tolerance) or confirmed by a cost-only pass; keeping that pass's residual
    (data − model) saves the result a model evaluation.  For a window of one
    chunk and the paper's model the pass's whole evaluation is kept too
    (:class:`~wheelcal.model.forward.EvaluatedModel`: ~100 B per sample), for
    the motion check at the result, and a gradient pass's reverse mode with it
    (:class:`~wheelcal.model.forward.ReverseAt`: 48 B per sample), for the closed
    loop's screen there.  With effects a gradient pass forms J: on a window of up to
    :data:`KEEP_JACOBIAN_SAMPLES` it is kept until the next point, for the Hessian the
    LM asks for there next.
    """

    def __init__(self, normal_fn, tc, v, layout: ParameterLayout, noise: NoiseModel) -> None:
        self._normal_fn = normal_fn
        self._args = (tc, v, layout)
        self._noise = noise
        self._params: CalibrationParams | None = None
        self._residual: np.ndarray | None = None
        self._evaluated: EvaluatedModel | None = None
        self._keep = tc.size <= CHUNK_SAMPLES and not layout.effects
        # with J, each chunk's, at ``_params`` (effects)
        self._jacobian_at: list[ModelOutput] | None = None
        self._keep_jacobian = tc.size <= KEEP_JACOBIAN_SAMPLES

    def _evaluated_at(self, params: CalibrationParams) -> EvaluatedModel | None:
        if not self._keep:
            return None
        tc, _, layout = self._args
        return EvaluatedModel(params, tc, evaluate(params, tc, layout))

    def __call__(self, params: CalibrationParams, want_jacobian: bool) -> NormalEquations:
        if want_jacobian:
            kept = self._jacobian_at if params is self._params else None
            return self._normal_fn(params, True, kept)
        self._jacobian_at = None
        evaluated = self._evaluated_at(params)
        if evaluated is None:
            residual = residual_of(params, *self._args)
        else:
            residual = np.subtract(self._args[1], evaluated.output.predicted_mps2)
        self._params, self._residual, self._evaluated = params, residual, evaluated
        rows = max(residual.shape[0] - self._noise.order, 0)
        # The priors' cost too, as every other evaluation has it: without it a cost-only
        # pass came out lower by Σ (x/σ)² than the gradient pass at the same point
        # (2.9 for a gyro's G at ~1 σ of its prior), and no step could beat it: "stalled".
        prior = effect_priors(params, self._args[2])
        cost = whitened_cost(residual, self._noise) + (0.0 if prior is None else prior[0])
        return NormalEquations(cost, None, None, 3 * rows)

    def gradient(self, params: CalibrationParams) -> NormalEquations:
        """Cost and gradient (:func:`gradient_pass`), the residual kept."""
        tc, v, layout = self._args
        residual = np.empty_like(v, dtype=float)
        evaluated = self._evaluated_at(params)
        output = evaluated.output if evaluated is not None else None
        reverse: list = []
        formed: list | None = [] if self._keep_jacobian else None
        out = gradient_pass(
            params,
            tc,
            v,
            layout,
            self._noise,
            residual_out=residual,
            output=output,
            reverse_out=reverse,
            evaluated_out=formed,
        )
        if reverse:  # the screen at the result takes its sums from this pass
            evaluated = dataclasses.replace(evaluated, reverse=reverse[0])
        self._params, self._residual, self._evaluated = params, residual, evaluated
        self._jacobian_at = formed or None
        return out

    def at(self, params: CalibrationParams) -> np.ndarray | None:
        """The kept residual if it was evaluated at ``params`` itself, else None."""
        return self._residual if params is self._params else None

    def evaluated_at(self, params: CalibrationParams) -> EvaluatedModel | None:
        """The kept evaluation if it was at ``params`` itself (and kept at all), else None."""
        return self._evaluated if params is self._params else None


def _same_point(a: CalibrationParams, b: CalibrationParams) -> bool:
    """True when a and b differ at most by ϑ₀ ± 2πk (same Jacobian, same normal equations)."""
    return (
        a.bench.tilt_rad == b.bench.tilt_rad
        and np.array_equal(a.bench.misalignment.matrix, b.bench.misalignment.matrix)
        and np.array_equal(a.sensor.offset_mps2, b.sensor.offset_mps2)
        and np.array_equal(a.spin.omega_radps, b.spin.omega_radps)
    )


def _residual_fn(
    tc: np.ndarray,
    v: np.ndarray,
    layout: ParameterLayout,
    noise: NoiseModel,
    nuisances: list[str] | None = None,
    gyro: tuple | None = None,
    gyro_rests: GyroRests | None = None,
):
    """Whitened normal equations of (model − data), for the LM (nuisances as extra columns).

    ``gyro`` = (times, samples, noise model) adds the gyroscope's stream, and
    ``gyro_rests`` its static readings at the rests (:mod:`.gyro_rests`).
    """
    extra = nuisance_extra(nuisances) if nuisances else None
    # The accelerometer does not see the gyro's reading: its stream is accumulated
    # without those (zero) rows, which come last in the layout.
    accel_layout = layout
    if gyro is not None and layout.effects[-1].stage == "gyro":
        accel_layout = dataclasses.replace(layout, effects=layout.effects[:-1])

    def normal(params: CalibrationParams, want_jacobian: bool, evaluated=None):
        """``evaluated``: the accelerometer's model with its J at ``params``, each chunk's."""
        acc = accumulate(
            params,
            tc,
            v,
            accel_layout,
            noise,
            jacobian=want_jacobian,
            extra=extra,
            evaluated=evaluated,
        )
        if gyro is None:
            return acc
        gyro_t, gyro_v, gyro_noise = gyro
        rate = accumulate_gyro(
            params, gyro_t, gyro_v, layout, gyro_noise, want_jacobian, rests=gyro_rests
        )
        return combined(acc, rate, accel_layout.size)

    return normal


def _ladder(samples: int) -> list[int]:
    """Sample counts of the stages between stage 1 and all ``samples``, smallest first."""
    targets = []
    target = samples // _LADDER_STEP
    while target >= _LADDER_MIN_SAMPLES:
        targets.append(target)
        target //= _LADDER_STEP
    return targets[::-1]


def _gradient_fn(tc: np.ndarray, v: np.ndarray, layout: ParameterLayout, noise: NoiseModel):
    """Cost and gradient of (model − data), no Hessian (see ``levenberg_marquardt``)."""

    def gradient(params: CalibrationParams) -> NormalEquations:
        return gradient_pass(params, tc, v, layout, noise)

    return gradient


def gyro_samples(recording: Recording, tc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centred times and samples of the recording's usable gyro rows."""
    gyro = getattr(recording, "gyro_radps", None)
    if gyro is None:
        raise RecordingError(f"{recording.source}: the recording has no gyroscope")
    valid = np.all(np.isfinite(gyro), axis=1)
    if valid.sum() < 100:
        raise RecordingError(
            f"{recording.source}: only {int(valid.sum())} usable gyro samples in the window"
        )
    return tc[valid], np.asarray(gyro)[valid]


def with_gyro_start(
    params: CalibrationParams, layout: ParameterLayout, gyro_t: np.ndarray, gyro: np.ndarray
) -> CalibrationParams:
    """``params`` with the gyro reading's w and b from a regression of the gyro on ω(t)."""
    reading = next(e for e in layout.effects if e.stage == "gyro")
    kin = wheel_kinematics(params, gyro_t, layout.effects)
    columns = [kin.omega_radps, np.ones_like(kin.omega_radps)]
    if reading.g_sensitivity:
        bench = params.bench
        force = bench_force(kin, bench.tilt_rad, bench.radius_m, params.gravity_mps2)
        columns += [force.accel_mps2[:, 0], force.accel_mps2[:, 1]]
    coef, *_ = np.linalg.lstsq(np.column_stack(columns), gyro, rcond=None)  # rows: w, b, G_X, G_Y
    effects = dict(params.effects)
    effects[reading.name] = coef.reshape(-1)
    return params.with_changes(effects=effects)
