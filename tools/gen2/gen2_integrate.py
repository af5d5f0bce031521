"""Time integration of one record for the second generator (scipy solve_ivp): a stepped sine, or a
continuous multisine (MultisineDrive).

The model's right-hand side is smooth inside each mode (which stops push, whether the amplifier
clips); the switches between modes are located as events, the integration stops there and restarts
in the new mode, so no step straddles a switch. A stop pushes while both its penetration p and its
raw force k_s p^n + c_s p' are positive: the event function is min(p / L, F / (k_s L^n)), which
crosses zero at contact (p = 0) and at the no-pull release (F = 0, before p = 0 when c_s > 0).
The equations are in README.md.
"""
import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq


def multisine_lines(low_hz, high_hz, period_s, odd):
    """The line numbers k of a multisine: k / period_s in [low_hz, high_hz], odd k only on the odd grid."""
    first = max(1, math.ceil(low_hz * period_s - 1e-9))
    return [k for k in range(first, math.floor(high_hz * period_s + 1e-9) + 1) if not odd or k % 2 == 1]


class MultisineDrive:
    """A multisine as a rig's generator makes it: sum_k a sin(2 pi f_k t + phi_k), continuous in t (the
    recording samples it; strokelab joins the samples by straight lines, so its drive differs from this
    one by the hold's error, as a real rig's does). Lines f_k = k / period_s in [low_hz, high_hz] (odd k
    only on the odd grid), equal amplitudes a = level sqrt(2 / lines) for an rms of level_v_rms, phases
    uniform in [0, 2 pi) from rng (Schoukens, Pintelon and Rolain, "Mastering System Identification in
    100 Exercises", 2012, Sec. 2.2: the random-phase multisine)."""

    def __init__(self, level_v_rms, low_hz, high_hz, period_s, odd, rng):
        ks = multisine_lines(low_hz, high_hz, period_s, odd)
        if not ks:
            raise ValueError(f"no multisine line in [{low_hz}, {high_hz}] Hz for a period of {period_s} s")
        self.omegas = 2 * math.pi * np.array(ks, dtype=float) / period_s
        self.phases = rng.uniform(0.0, 2 * math.pi, len(ks))
        self.amplitude = level_v_rms * math.sqrt(2.0 / len(ks))
        self.level_v_rms = level_v_rms
        self.highest_rad_s = float(self.omegas[-1])

    def __call__(self, t):
        if isinstance(t, float):
            return float(self.amplitude * np.sum(np.sin(self.omegas * t + self.phases)))
        t = np.asarray(t, dtype=float)
        return self.amplitude * np.sin(np.multiply.outer(t, self.omegas) + self.phases).sum(axis=-1)


class Dynamics:
    """The equations of motion of one record: model (gen2_model dict) and drive A sin(w t + phase), or
    `multisine` (a MultisineDrive; amplitude_v and omega_rad_s are then not used)."""

    def __init__(self, model, amplitude_v, omega_rad_s, phase_rad=0.0, multisine=None):
        self.multisine = multisine
        if multisine is not None:
            # The coil's heating follows the drive's power: a sine of the same rms has amplitude sqrt(2) rms.
            amplitude_v, omega_rad_s = math.sqrt(2.0) * multisine.level_v_rms, multisine.highest_rad_s
        self.m = model["m_p"]
        self.k_p, self.k2, self.k3 = model["k_p"], model["k2"], model["k3"]
        # Coil heating (gain_compression): the record's drive warms the coil, whose resistance grows by
        # 1 + alpha_g A^2 (the power it takes); the current per volt and the back-EMF's damping fall by it.
        compression = 1.0 / (1.0 + model["alpha_g"] * amplitude_v ** 2)
        self.g = model["g"] * compression
        self.c_emf = model["c_emf"] * compression
        self.c_mech = model["c_p"] - model["c_emf"]   # the back-EMF part moves into the coupling
        self.c2, self.c_x2 = model["c2"], model["c_x2"]
        self.b1, self.b2 = model["b1"], model["b2"]
        self.friction, self.v_s = model["friction_n"], model["friction_velocity"]
        self.d, self.d_upper = model["d"], model["d_upper"]
        self.k_s, self.c_s = model["k_s"], model["c_s"]
        self.n = 1.5 if model["contact_law"] == "hertzian" else 1.0
        self.limit = model["amplifier_limit_v"]
        self.amplitude, self.omega, self.phase = amplitude_v, omega_rad_s, phase_rad
        self.coil = model["L"] > 0
        self.tau = model["L"] / model["R"] * compression if self.coil else 0.0
        self.creep = model["k_m"] > 0
        self.k_m, self.tau_m = model["k_m"], model["tau_m"]
        self.mount = model["f_mount"] > 0
        if self.mount:
            self.m_b = model["m_mount"]
            self.k_b = self.m_b * (2 * math.pi * model["f_mount"]) ** 2
            self.c_b = 2 * model["zeta_mount"] * math.sqrt(self.k_b * self.m_b)
            w_b = 2 * math.pi * model["f_mount"]
            self.sigma_b = model["zeta_mount"] * w_b
            self.omega_db = w_b * math.sqrt(1.0 - model["zeta_mount"] ** 2)
        self.segment_start_s = 0.0
        self.has_lower = math.isfinite(self.d) and self.k_s + self.c_s > 0
        self.has_upper = math.isfinite(self.d_upper) and self.k_s + self.c_s > 0
        # (A multisine's peak is at most the sum of its lines' amplitudes.)
        peak_v = amplitude_v if multisine is None else multisine.amplitude * len(multisine.omegas)
        self.clips = math.isfinite(self.limit) and self.limit < peak_v
        # State: x, v [, F_e (coil force Bl0 i, N)] [, y, w (stop flexure)] [, F_m (creep force, N)].
        self.i_fe = 2 if self.coil else None
        self.i_y = (3 if self.coil else 2) if self.mount else None
        self.i_m = 2 + self.coil + 2 * self.mount if self.creep else None
        self.size = 2 + self.coil + 2 * self.mount + self.creep
        self.length_m = abs(self.d) if math.isfinite(self.d) and self.d != 0 else 1e-3
        w_p = math.sqrt(self.k_p / self.m) if self.k_p > 0 else omega_rad_s
        scale = [self.length_m, self.length_m * max(w_p, omega_rad_s)]
        if self.coil:
            scale.append(max(self.g * amplitude_v, 1e-6))
        if self.mount:
            w_b = 2 * math.pi * model["f_mount"]
            scale += [self.length_m * 1e-3, self.length_m * 1e-3 * w_b]
        if self.creep:
            scale.append(self.k_m * self.length_m)
        self.scale = np.array(scale)

    # --- pieces of the right-hand side (scalars or arrays) ---
    def raw_drive(self, t):
        if self.multisine is not None:
            return self.multisine(t)
        sin = math.sin if isinstance(t, float) else np.sin
        return self.amplitude * sin(self.omega * t + self.phase)

    def drive(self, t, clip):
        return self.raw_drive(t) if clip == 0 else clip * self.limit + 0.0 * t

    def _power(self, p):
        if self.n == 1.0:
            return p
        return math.copysign(abs(p) ** self.n, p) if isinstance(p, float) else np.sign(p) * np.abs(p) ** self.n

    def mount_free(self, t, s):
        """The stop's flexure off contact: a free damped oscillation from its state at segment_start_s,
        held constant in the state's slots, so that the solver does not follow the ringing."""
        y0, w0 = s[self.i_y], s[self.i_y + 1]
        tau = t - self.segment_start_s
        if isinstance(tau, float):
            decay, cos, sin = math.exp(-self.sigma_b * tau), math.cos(self.omega_db * tau), math.sin(self.omega_db * tau)
        else:
            decay, cos, sin = np.exp(-self.sigma_b * tau), np.cos(self.omega_db * tau), np.sin(self.omega_db * tau)
        b = (w0 + self.sigma_b * y0) / self.omega_db
        y = decay * (y0 * cos + b * sin)
        w = decay * ((self.omega_db * b - self.sigma_b * y0) * cos - (self.sigma_b * b + self.omega_db * y0) * sin)
        return y, w

    def mount_state(self, t, s, mode):
        if mode[0]:
            return s[self.i_y], s[self.i_y + 1]
        return self.mount_free(t, s)

    def lower_penetration(self, t, s, mode):
        p = self.d - s[0]
        pd = -s[1]
        if self.mount:
            y, w = self.mount_state(t, s, mode)
            p = p + y
            pd = pd + w
        return p, pd

    def upper_penetration(self, t, s, mode):
        return s[0] - self.d_upper, s[1]

    def stop_force(self, p, pd):
        return self.k_s * self._power(p) + self.c_s * pd

    def rhs(self, t, s, mode):
        """ds/dt in mode (lower_on, upper_on, clip); s is (size,) or (size, samples)."""
        lower_on, upper_on, clip = mode
        x, v = s[0], s[1]
        u = self.drive(t, clip)
        phi = 1.0 + self.b1 * x + self.b2 * x * x
        out = [v, None]
        if self.coil:
            fe = s[self.i_fe]
            coil_force = phi * fe
        else:
            coil_force = phi * (self.g * u - self.c_emf * phi * v)
        suspension = (self.k_p * x + self.k2 * x * x + self.k3 * x * x * x
                      + (self.c_mech + self.c_x2 * x * x) * v + self.c2 * v * abs(v))
        if self.friction:
            tanh = math.tanh if isinstance(v, float) else np.tanh
            suspension = suspension + self.friction * tanh(v / self.v_s)
        if self.creep:
            suspension = suspension + s[self.i_m]
        force = coil_force - suspension
        lower = 0.0
        if lower_on:
            lower = self.stop_force(*self.lower_penetration(t, s, mode))
            force = force + lower
        if upper_on:
            force = force - self.stop_force(*self.upper_penetration(t, s, mode))
        out[1] = force / self.m
        if self.coil:
            out.append((self.g * u - self.c_emf * phi * v - fe) / self.tau)
        if self.mount:
            if lower_on:
                y, w = s[self.i_y], s[self.i_y + 1]
                out += [w, (-self.k_b * y - self.c_b * w - lower) / self.m_b]
            else:
                out += [0.0 * s[0], 0.0 * s[0]]
        if self.creep:
            # Suspension creep (suspension_creep): a Maxwell element, spring k_m in series with a dashpot
            # k_m tau_m, beside the suspension (the standard linear solid; R. S. Lakes, "Viscoelastic
            # Materials", Cambridge University Press 2009, Sec. 2.3): F_m' = k_m v - F_m / tau_m.
            out.append(self.k_m * v - s[self.i_m] / self.tau_m)
        return out

    def blocked_force(self, t, s, mode):
        """f = m_p x'' (+ m_b y'' of the stop's flexure): the force the housing puts on the sensor."""
        ds = self.rhs(t, s, mode)
        f = self.m * ds[1]
        if self.mount:
            if mode[0]:
                f = f + self.m_b * ds[self.i_y + 1]
            else:
                y, w = self.mount_free(t, s)
                f = f - self.k_b * y - self.c_b * w
        return f, ds[1]

    def begin_segment(self, t0_s):
        self.segment_start_s = t0_s

    def end_segment(self, t1_s, state, mode):
        """The state at the segment's end in the variables the next segment starts from."""
        state = np.array(state)
        if self.mount and not mode[0]:
            state[self.i_y], state[self.i_y + 1] = self.mount_free(t1_s, state)
        return state

    # --- switching ---
    def _stop_event(self, penetration, mode, direction):
        k_ref = self.k_s * self.length_m ** self.n if self.k_s > 0 else 1.0

        def event(t, s):
            p, pd = penetration(float(t), s.tolist(), mode)
            if self.c_s == 0:
                return p / self.length_m
            return min(p / self.length_m, self.stop_force(p, pd) / k_ref)
        event.terminal = True
        event.direction = direction
        return event

    def events(self, mode):
        """Event functions leaving mode, each with the mode it leads to."""
        lower_on, upper_on, clip = mode
        out = []
        if self.has_lower:
            out.append((self._stop_event(self.lower_penetration, mode, -1 if lower_on else 1),
                        (not lower_on, upper_on, clip)))
        if self.has_upper:
            out.append((self._stop_event(self.upper_penetration, mode, -1 if upper_on else 1),
                        (lower_on, not upper_on, clip)))
        if self.clips:
            def above(t, s):
                return self.raw_drive(float(t)) - self.limit

            def below(t, s):
                return self.raw_drive(float(t)) + self.limit
            for fn, sign in ((above, 1), (below, -1)):
                fn.terminal = True
            if clip == 0:
                above.direction, below.direction = 1, -1
                out += [(above, (lower_on, upper_on, 1)), (below, (lower_on, upper_on, -1))]
            elif clip == 1:
                above.direction = -1
                out.append((above, (lower_on, upper_on, 0)))
            else:
                below.direction = 1
                out.append((below, (lower_on, upper_on, 0)))
        return out

    def initial_mode(self):
        u0 = self.raw_drive(0.0)
        clip = 0
        if self.clips and abs(u0) > self.limit:
            clip = 1 if u0 > 0 else -1
        return (False, False, clip)


SAMPLES_PER_STEP = 16


def missed_contact(dyn, sol, mode):
    """(time, mode) of the first stop entry that solve_ivp stepped over, or None.

    solve_ivp sees an event only where its function changes sign between two step ends. A step longer
    than a grazing dip below a stop steps over the whole contact: the truth then lacks an impact (at
    rtol 1e-10, a 1.5 um contact at 8 Hz was missed on every other period, which made a period-1 orbit
    look period-2). Each step's dense output is sampled at SAMPLES_PER_STEP points and the first rise of
    a penetration from <= 0 to > 0 is located by brentq."""
    entries = []
    if dyn.has_lower and not mode[0]:
        entries.append((dyn.lower_penetration, (True, mode[1], mode[2])))
    if dyn.has_upper and not mode[1]:
        entries.append((dyn.upper_penetration, (mode[0], True, mode[2])))
    if not entries or len(sol.t) < 2:
        return None
    fractions = np.arange(SAMPLES_PER_STEP + 1) / SAMPLES_PER_STEP
    times = (sol.t[:-1, None] + np.diff(sol.t)[:, None] * fractions).ravel()
    states = sol.sol(times)
    first = None
    for penetration, next_mode in entries:
        p = penetration(times, states, mode)[0]
        rises = np.flatnonzero((p[:-1] <= 0) & (p[1:] > 0))
        if len(rises) and (first is None or times[rises[0]] < first[0]):
            i = rises[0]
            def gap(t, penetration=penetration):
                return penetration(t, sol.sol(t), mode)[0]
            first = (brentq(gap, times[i], times[i + 1], xtol=1e-15, rtol=1e-15), next_mode)
    return first


def simulate(dyn, end_s, sample_times_s, method="DOP853", rtol=1e-10, max_segments=10**6):
    """From rest at t = 0 to end_s; returns dict of x, v, a, f at sample_times_s (sorted) and counts."""
    times = np.asarray(sample_times_s, dtype=float)
    out = {key: np.empty(len(times)) for key in ("x", "v", "a", "f")}
    atol = rtol * dyn.scale
    state = np.zeros(dyn.size)
    mode = dyn.initial_mode()
    t0, first, segments, impacts, step_s = 0.0, 0, 0, 0, None
    while t0 < end_s:
        segments += 1
        if segments > max_segments:
            raise RuntimeError(f"more than {max_segments} mode switches before t = {t0} s (chattering?)")
        pairs = dyn.events(mode)
        dyn.begin_segment(t0)
        # A new segment starts with the last one's step (solve_ivp's own first guess can be so large
        # that a trial stage of a nonlinear model overflows; such a step is rejected, never used).
        first_step = min(step_s, end_s - t0) if step_s else None
        with np.errstate(over="ignore", invalid="ignore"):
            # The right-hand side on Python floats (several times faster than on numpy scalars).
            sol = solve_ivp(lambda t, s, mode=mode: dyn.rhs(float(t), s.tolist(), mode), (t0, end_s), state, method=method,
                            rtol=rtol, atol=atol, events=[e for e, _ in pairs] or None, dense_output=True,
                            first_step=first_step)
        if len(sol.t) >= 3:
            step_s = sol.t[-2] - sol.t[-3]
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed at t = {sol.t[-1]} s: {sol.message}")
        t1, next_state, next_mode = sol.t[-1], sol.y[:, -1], mode
        if sol.status == 1:
            fired = [i for i, te in enumerate(sol.t_events) if len(te)]
            i = min(fired, key=lambda j: sol.t_events[j][0])
            t1, next_state, next_mode = sol.t_events[i][0], sol.y_events[i][0], pairs[i][1]
        missed = missed_contact(dyn, sol, mode)
        if missed is not None and missed[0] < t1:
            t1, next_mode = missed
            next_state = sol.sol(t1)
        if next_mode[0] and not mode[0]:
            impacts += 1
        last = np.searchsorted(times, t1, side="right" if t1 >= end_s else "left")
        if last > first:
            ts = times[first:last]
            s = sol.sol(ts)
            f, a = dyn.blocked_force(ts, s, mode)
            out["x"][first:last], out["v"][first:last] = s[0], s[1]
            out["a"][first:last], out["f"][first:last] = a, f
            first = last
        t0, state, mode = t1, dyn.end_segment(t1, next_state, mode), next_mode
    if first < len(times):
        raise RuntimeError("sample times beyond the simulated span")
    out["segments"], out["lower_impacts"] = segments, impacts
    return out
