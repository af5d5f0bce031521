"""The actuator model of the second generator: parameters, presets, model JSON, effects.

Written from the paper (Eq. 2 in its continuous form, Table 2) and the parameter table of
core/include/strokelab/model/model.h (keys, JSON names, units), extended by the effects issue 13
adds and by two effects no library holds. The equations are in README.md.
"""
import json
import math

INF = math.inf

# (key, JSON name, unit, paper value, description). The first block is strokelab's own table
# (model.h): a strokelab model JSON file loads. The second block is this generator's alone.
LIBRARY_PARAMETERS = [
    ("m_p", "mass_kg", "kg", 0.032, "proof mass"),
    ("c_p", "damping_n_s_per_m", "N s/m", 1.3, "suspension damping (with back-EMF)"),
    ("k_p", "stiffness_n_per_m", "N/m", 124.0, "suspension stiffness"),
    ("k2", "quadratic_stiffness_n_per_m2", "N/m^2", 0.0, "quadratic suspension stiffness"),
    ("k3", "cubic_stiffness_n_per_m3", "N/m^3", 0.0, "cubic suspension stiffness"),
    ("g", "gain_n_per_v", "N/V", 0.3, "force per drive volt (amplifier x coil)"),
    ("d", "lower_stop_m", "m", -1e-3, "lower end stop position (-inf: none)"),
    ("d_upper", "upper_stop_m", "m", INF, "upper end stop position (+inf: none)"),
    ("k_s", "contact_stiffness", "N/m or N/m^1.5", 1.3e6, "end-stop contact stiffness"),
    ("c_s", "contact_damping_n_s_per_m", "N s/m", 0.0, "end-stop contact damping (only pushes)"),
    ("friction_n", "friction_force_n", "N", 0.0, "dry friction level F_c"),
    ("friction_velocity", "friction_velocity_m_per_s", "m/s", 1e-3, "friction smoothing velocity v_s"),
    ("amplifier_limit_v", "amplifier_limit_v", "V", INF, "drive clipping level (+inf: none)"),
]
GEN2_PARAMETERS = [
    ("b1", "force_factor_b1_per_m", "1/m", 0.0, "force factor g(x) = g (1 + b1 x + b2 x^2)"),
    ("b2", "force_factor_b2_per_m2", "1/m^2", 0.0, "force factor, quadratic (< 0: falls off)"),
    ("c2", "quadratic_damping_n_s2_per_m2", "N s^2/m^2", 0.0, "quadratic damping c2 v|v|"),
    ("L", "coil_inductance_h", "H", 0.0, "coil inductance (0: the coil's pole is ignored)"),
    ("R", "coil_resistance_ohm", "Ohm", 3.0, "coil resistance (paper sec. 3: about 3 Ohm)"),
    ("c_emf", "back_emf_damping_n_s_per_m", "N s/m", 1.0, "the back-EMF part of c_p, (Bl)^2/R"),
    ("c_x2", "position_damping_n_s_per_m3", "N s/m^3", 0.0, "displacement-dependent damping c_x2 x^2 v"),
    ("f_mount", "stop_mount_frequency_hz", "Hz", 0.0, "lower stop on a flexure: its frequency (0: rigid)"),
    ("m_mount", "stop_mount_mass_kg", "kg", 0.01, "mass of the lower stop's flexure"),
    ("zeta_mount", "stop_mount_damping_ratio", "1", 0.02, "damping ratio of the lower stop's flexure"),
    ("k_m", "creep_stiffness_n_per_m", "N/m", 0.0, "suspension creep: Maxwell element's spring (0: none)"),
    ("tau_m", "creep_time_s", "s", 5e-3, "suspension creep: Maxwell element's relaxation time"),
    ("alpha_g", "gain_compression_per_v2", "1/V^2", 0.0, "coil heating: R grows by 1 + alpha_g A^2"),
    ("a_s", "sensor_quadratic_per_v", "1/V", 0.0, "response sensor's quadratic term: y + a_s y^2"),
]
PARAMETERS = LIBRARY_PARAMETERS + GEN2_PARAMETERS
_BY_NAME = {}
for _p in PARAMETERS:
    _BY_NAME[_p[0]] = _p
    _BY_NAME[_p[1]] = _p

# Effect name -> the parameter it sets. The library's seven keep strokelab's ids (diagnose.h);
# hertzian_contact also switches the contact law.
EFFECTS = {
    "cubic_stiffness": "k3",
    "quadratic_stiffness": "k2",
    "hertzian_contact": "k_s",
    "contact_damping": "c_s",
    "second_stop": "d_upper",
    "dry_friction": "friction_n",
    "amplifier_saturation": "amplifier_limit_v",
    "force_factor": "b2",
    "quadratic_damping": "c2",
    "coil_inductance": "L",
    "stop_mount": "f_mount",
    "position_damping": "c_x2",
    "suspension_creep": "k_m",
    "gain_compression": "alpha_g",
    "sensor_quadratic": "a_s",
}
LIBRARY_EFFECTS = ["cubic_stiffness", "quadratic_stiffness", "hertzian_contact", "contact_damping",
                   "second_stop", "dry_friction", "amplifier_saturation"]
NEW_EFFECTS = ["force_factor", "quadratic_damping", "coil_inductance"]
UNLISTED_EFFECTS = ["stop_mount", "position_damping", "suspension_creep", "gain_compression", "sensor_quadratic"]


class ModelError(ValueError):
    """A model, key or value that is wrong; the message names it."""


def find_parameter(name):
    try:
        return _BY_NAME[name]
    except KeyError:
        keys = ", ".join(p[0] for p in PARAMETERS)
        raise ModelError(f"unknown parameter '{name}'; valid keys: {keys} (or their JSON names)") from None


def preset(name):
    """'paper' (Table 2, one-sided stop at d = -1 mm) or 'linear' (no stops)."""
    model = {p[0]: p[3] for p in PARAMETERS}
    model["contact_law"] = "linear"
    if name == "linear":
        model["d"] = -INF
    elif name != "paper":
        raise ModelError(f"unknown preset '{name}'; valid: paper, linear")
    return model


def set_value(model, key_or_name, value):
    key = find_parameter(key_or_name)[0]
    if value is None:
        if key not in ("d", "d_upper", "amplifier_limit_v"):
            raise ModelError(f"{key}: null only means 'absent' for stops and limits")
        value = {"d": -INF, "d_upper": INF, "amplifier_limit_v": INF}[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelError(f"{key}: expected a number, got {value!r}")
    model[key] = float(value)


def apply_override(model, assignment):
    """'key=value' (--set); value 'inf'/'-inf' allowed for stops and limits."""
    key, sep, text = assignment.partition("=")
    if not sep:
        raise ModelError(f"--set '{assignment}': expected KEY=VALUE")
    if key.strip() == "contact_law":
        set_contact_law(model, text.strip())
        return
    try:
        value = float(text)
    except ValueError:
        raise ModelError(f"--set {key}: '{text}' is not a number") from None
    set_value(model, key.strip(), value)


def set_contact_law(model, law):
    if law not in ("linear", "hertzian"):
        raise ModelError(f"contact_law: expected 'linear' or 'hertzian', got '{law}'")
    model["contact_law"] = law


def apply_effect(model, assignment):
    """'name=value' (--effect): sets the effect's parameter (hertzian_contact: k_s in N/m^1.5)."""
    name, sep, text = assignment.partition("=")
    name = name.strip()
    if not sep or name not in EFFECTS:
        raise ModelError(f"--effect '{assignment}': expected NAME=VALUE with NAME one of {', '.join(EFFECTS)}")
    try:
        value = float(text)
    except ValueError:
        raise ModelError(f"--effect {name}: '{text}' is not a number") from None
    if name == "hertzian_contact":
        set_contact_law(model, "hertzian")
    set_value(model, EFFECTS[name], value)
    return name, EFFECTS[name], value


def load_model(spec):
    """A preset name, or a JSON file: a preset name, or an object of parameters as strokelab reads."""
    if spec in ("paper", "linear"):
        return preset(spec)
    try:
        with open(spec) as f:
            data = json.load(f)
    except OSError as e:
        raise ModelError(f"--model '{spec}': {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise ModelError(f"--model '{spec}': line {e.lineno}: {e.msg}") from None
    if isinstance(data, str):
        return preset(data)
    if not isinstance(data, dict):
        raise ModelError(f"--model '{spec}': expected a preset name or an object of model parameters")
    model = preset(data.get("preset", "paper"))
    for key, value in data.items():
        if key == "preset":
            continue
        try:
            if key == "contact_law":
                set_contact_law(model, value)
            else:
                set_value(model, key, value)
        except ModelError as e:
            raise ModelError(f"--model '{spec}': {e}") from None
    return model


def validate(model):
    """Physical sense, by key; raises ModelError."""
    def need(ok, key, what):
        if not ok:
            raise ModelError(f"{key}: {what}, got {model[key]!r}")
    for key in ("m_p", "c_p", "k_p", "g", "k_s", "c_s", "friction_n", "c2", "L", "R", "c_emf", "f_mount", "k_m",
                "alpha_g"):
        need(math.isfinite(model[key]) and model[key] >= 0, key, "must be a finite number >= 0")
    need(model["m_p"] > 0, "m_p", "must be > 0")
    need(model["friction_velocity"] > 0 and math.isfinite(model["friction_velocity"]), "friction_velocity", "must be > 0")
    need(model["d"] <= 0, "d", "must be <= 0 or -inf")
    need(model["d_upper"] >= 0, "d_upper", "must be >= 0 or +inf")
    need(model["amplifier_limit_v"] > 0, "amplifier_limit_v", "must be > 0 or +inf")
    need(model["c_emf"] <= model["c_p"], "c_emf", f"the back-EMF part of c_p must not exceed c_p = {model['c_p']}")
    need(model["R"] > 0 or model["L"] == 0, "R", "must be > 0 when the coil has an inductance")
    if model["f_mount"] > 0:
        need(model["m_mount"] > 0, "m_mount", "must be > 0 when the stop has a flexure")
        need(0 <= model["zeta_mount"] < 1, "zeta_mount", "must be in [0, 1) (an underdamped flexure)")
    need(model["tau_m"] > 0 and math.isfinite(model["tau_m"]), "tau_m", "must be > 0")
    for key in ("k2", "k3", "b1", "b2", "c_x2", "a_s"):
        need(math.isfinite(model[key]), key, "must be finite")


def json_number(value):
    return value if math.isfinite(value) else None


def to_json(model, gen2_keys=True):
    """By JSON names, like strokelab's ModelToJson (+-inf as null); the gen2 keys only when set."""
    out = {}
    for key, name, _unit, default, _desc in PARAMETERS:
        if (key, name, _unit, default, _desc) in GEN2_PARAMETERS and not gen2_keys:
            continue
        out[name] = json_number(model[key])
    out["contact_law"] = model["contact_law"]
    return out


def library_part(model):
    """The model as strokelab reads it (its own keys only)."""
    out = {name: json_number(model[key]) for key, name, *_ in LIBRARY_PARAMETERS}
    out["contact_law"] = model["contact_law"]
    return out
