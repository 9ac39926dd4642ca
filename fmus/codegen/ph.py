"""Port-Hamiltonian spec (YAML) -> config.h + model.c for the shared FMI layer (fmus/layer/model.h).

A spec declares states, parameters, H(x), J, R, G and optionally the feed-through P, S, N; the
structure may depend on the states. The gradient, Hessian and structure derivatives come from
sympy; the discrete gradient is picked from the form of H: midpoint for quadratic H, the exact
coordinate-wise difference quotient for separable H, Gonzalez's otherwise. The step itself is
fmus/codegen/ph_step.h. See specs/README.md for the format.

    python fmus/codegen/ph.py specs/<name>.yaml OUT_DIR
"""
import sys
import uuid
from pathlib import Path

import numpy as np
import sympy as sp
import yaml
from sympy.parsing.sympy_parser import parse_expr
from sympy.printing.c import C99CodePrinter

from wavecosim.errors import ConfigError

STEP_HEADER = Path(__file__).resolve().parent / "ph_step.h"
RESERVED = {"gamma", "H", "port_mode", "newton_max_iter"}
SAMPLES = 300
SMALL_DELTA = 1e-7
GAUSS_SWITCH = 1e-2


class Spec:
    """A parsed, checked spec: symbols, expressions and variable tables."""

    def __init__(self, path, data):
        self.path, self.data = Path(path), data
        self.name = _require(self, data, "model", str)
        self.params = _variables(self, "parameters", required=False)
        self.states = _variables(self, "states", required=True)
        self.psym = {k: sp.Symbol(k, real=True) for k in self.params}
        self.xsym = [sp.Symbol(k, real=True) for k in self.states]
        self.ports = _ports(self)
        _check_names(self, _mapping(self, "outputs"))
        self.H = _expr(self, "H", data.get("H"))
        n, m = len(self.states), len(self.ports)
        self.J = _matrix(self, "J", n, n, required=True)
        self.R = _matrix(self, "R", n, n)
        self.G = _matrix(self, "G", n, m, required=True)
        self.P = _matrix(self, "P", n, m)
        self.S = _matrix(self, "S", m, m)
        self.N = _matrix(self, "N", m, m)
        self.outputs = {k: (_expr(self, f"outputs.{k}", v[0]), *_pad(v[1:], 2))
                        for k, v in _mapping(self, "outputs").items()}

    def error(self, key, problem):
        """A ConfigError naming this file and the key."""
        return ConfigError(f"{self.path}: {key}: {problem}")

    def states_list(self):
        """State names in order."""
        return list(self.states)

    def symbols(self):
        """{name: sympy symbol} of parameters and states."""
        return {**self.psym, **dict(zip(self.states, self.xsym))}

    def parameter_values(self):
        """{parameter symbol: start value}, used by the sampled checks."""
        return {self.psym[k]: float(v[0]) for k, v in self.params.items()}


def _check_names(spec, outputs):
    """Every FMU variable name (parameters, states, port variables, outputs) is used once."""
    seen = set(RESERVED)
    port_vars = [[f"{v}{p['suffix']}" for v in "abef"] + [p["input"]] for p in spec.ports]
    groups = [("parameters", spec.params), ("states", spec.states),
              *((f"ports[{j}]", names) for j, names in enumerate(port_vars)), ("outputs", outputs)]
    for key, names in groups:
        for name in names:
            if name in seen:
                raise spec.error(f"{key}.{name}", "name already used by another variable")
            seen.add(name)


def _require(spec, data, key, kind):
    """data[key], which must exist and be of type kind."""
    if key not in data:
        raise spec.error(key, "missing")
    if not isinstance(data[key], kind):
        raise spec.error(key, f"must be a {kind.__name__}")
    return data[key]


def _mapping(spec, key):
    """{name: list} of a mapping key (scalars become one-element lists)."""
    value = spec.data.get(key) or {}
    if not isinstance(value, dict):
        raise spec.error(key, "must be a mapping")
    return {k: v if isinstance(v, list) else [v] for k, v in value.items()}


def _pad(values, n):
    """values as strings, padded with "" to length n."""
    return [str(v) for v in values] + [""] * (n - len(values))


def _variables(spec, key, required):
    """{name: [start, unit, description]} from `name: [start, unit, description]` entries."""
    if required and not spec.data.get(key):
        raise spec.error(key, "missing or empty")
    out = {}
    for name, v in _mapping(spec, key).items():
        if name in RESERVED or not str(name).isidentifier():
            raise spec.error(f"{key}.{name}", "reserved or not a C identifier")
        try:
            out[name] = [float(v[0]), *_pad(v[1:], 2)]
        except (TypeError, ValueError):
            raise spec.error(f"{key}.{name}", "start value must be a number") from None
    return out


def _ports(spec):
    """Port channels: variable suffix, physical input, causality, units."""
    ports = spec.data.get("ports")
    if not isinstance(ports, list) or not ports:
        raise spec.error("ports", "must be a non-empty list")
    out = []
    for j, p in enumerate(ports):
        key = f"ports[{j}]"
        if not isinstance(p, dict) or "input" not in p:
            raise spec.error(key, "needs `input` (the physical input variable)")
        if p.get("causality") not in ("effort_in", "flow_in"):
            raise spec.error(f"{key}.causality", "must be effort_in or flow_in")
        suffix = f"_{p['name']}" if p.get("name") else ""
        units = _pad(p.get("units", []), 2)
        out.append(dict(suffix=suffix, input=p["input"], effort_in=p["causality"] == "effort_in",
                        effort_unit=units[0], flow_unit=units[1]))
    return out


def _expr(spec, key, text):
    """A sympy expression of parameters and states."""
    if text is None:
        raise spec.error(key, "missing")
    try:
        e = parse_expr(str(text), local_dict=spec.symbols())
    except Exception as exc:
        raise spec.error(key, f"cannot parse {text!r}: {exc}") from None
    unknown = {str(s) for s in getattr(e, "free_symbols", set())} - set(spec.symbols())
    if unknown:
        raise spec.error(key, f"unknown symbol(s) {', '.join(sorted(unknown))}")
    return sp.sympify(e)


def _matrix(spec, key, rows, cols, required=False):
    """A rows x cols sympy matrix from a list of rows (zeros when absent and optional)."""
    value = spec.data.get(key)
    if value is None:
        if required:
            raise spec.error(key, "missing")
        return sp.zeros(rows, cols)
    if not isinstance(value, list) or len(value) != rows or \
            any(not isinstance(row, list) or len(row) != cols for row in value):
        raise spec.error(key, f"must be a {rows} x {cols} list of rows")
    return sp.Matrix([[_expr(spec, f"{key}[{i}][{k}]", v) for k, v in enumerate(row)]
                      for i, row in enumerate(value)])


def load(path) -> Spec:
    """Reads and checks one spec file; raises ConfigError naming the file and the key."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: the spec must be a mapping")
    spec = Spec(path, data)
    check(spec)
    return spec


def sample_states(spec, rng):
    """SAMPLES states around the start values, at radii 0.1 to 100 times `scale` (default 1)."""
    scale = spec.data.get("scale", {}) or {}
    s = np.array([float(scale.get(k, 1.0)) for k in spec.states])
    x0 = np.array([v[0] for v in spec.states.values()])
    radius = 10.0 ** rng.uniform(-1, 2, size=(SAMPLES, 1))
    return x0 + radius * s * rng.standard_normal((SAMPLES, len(s)))


def check(spec):
    """J and N skew, [[R, P], [P^T, S]] positive semi-definite and H >= H_min on sampled states."""
    for key in ("J", "N"):
        M = getattr(spec, key)
        if sp.simplify(M + M.T) != sp.zeros(*M.shape):
            raise spec.error(key, "is not skew-symmetric")
    diss = sp.BlockMatrix([[spec.R, spec.P], [spec.P.T, spec.S]]).as_explicit()
    pv = spec.parameter_values()
    diss_f = sp.lambdify(spec.xsym, diss.subs(pv), "numpy")
    H_f = sp.lambdify(spec.xsym, spec.H.subs(pv), "numpy")
    h_min = float(spec.data.get("H_min", 0.0))
    for x in sample_states(spec, np.random.default_rng(0)):
        D = np.array(diss_f(*x), dtype=float)
        D = 0.5 * (D + D.T)
        if np.linalg.eigvalsh(D).min() < -1e-12 * max(1.0, np.abs(D).max()):
            raise spec.error("R", f"[[R, P], [P^T, S]] is not positive semi-definite at state "
                                  f"{_fmt(spec, x)}")
        H = float(H_f(*x))
        if not H >= h_min - 1e-12 * abs(h_min):
            raise spec.error("H", f"H = {H:.6g} < H_min = {h_min:g} at state {_fmt(spec, x)}")


def _fmt(spec, x):
    """A sampled state for an error message."""
    return "{" + ", ".join(f"{k}: {v:.4g}" for k, v in zip(spec.states, x)) + "}"


def classify(spec):
    """'quadratic', 'separable' or 'general': which discrete gradient H gets."""
    try:
        if sp.Poly(spec.H, *spec.xsym).total_degree() <= 2:
            return "quadratic"
    except sp.PolynomialError:
        pass
    for term in sp.Add.make_args(sp.expand(spec.H)):
        if len(term.free_symbols & set(spec.xsym)) > 1:
            return "general"
    return "separable"


def _near(spec, i):
    """C condition: x'_i is within GAUSS_SWITCH x scale of x_i, where the difference quotient would
    lose digits to cancellation."""
    scale = float((spec.data.get("scale") or {}).get(spec.states_list()[i], 1.0))
    return f"fabs(w[{i}] - x[{i}]) <= {GAUSS_SWITCH * scale!r}"


def _gauss_mean(f, xi, a, b):
    """The mean of f(xi) over [a, b] by 4-point Gauss-Legendre: the difference quotient of an
    antiderivative of f, without cancellation, exact to roundoff for |b - a| small."""
    nodes, weights = np.polynomial.legendre.leggauss(4)
    return sum(sp.Float(wk / 2) * f.subs(xi, a + sp.Float((tk + 1) / 2) * (b - a)) for tk, wk in zip(nodes, weights))


def _branches(near, target, pr, small, large):
    """C if/else assigning target from `small` when `near` holds, from `large` otherwise."""
    return (f"    if ({near}) {{\n    {pr.assign([target], [small])}\n    }} else {{\n"
            f"    {pr.assign([target], [large])}\n    }}")


def _quotients(spec, x, xn):
    """(i, (quotient, polynomial form or None)) for the non-quadratic terms h_i of a separable H:
    (h_i(x'_i) - h_i(x_i)) / (x'_i - x_i), divided out exactly when h_i is a polynomial (no
    cancellation, valid at x'_i = x_i)."""
    out = []
    for i, h_i in enumerate(_separable_parts(spec)):
        xi = spec.xsym[i]
        poly = h_i.is_polynomial(xi)
        if poly and sp.Poly(h_i, xi).total_degree() <= 2:
            continue
        raw = (h_i.subs(xi, xn[i]) - h_i.subs(xi, x[i])) / (xn[i] - x[i])
        out.append((i, (raw, sp.expand(sp.cancel(raw)) if poly else None)))
    return out


def _separable_parts(spec):
    """h_i(x_i) for H = sum_i h_i(x_i) + const."""
    parts = [sp.Integer(0)] * len(spec.xsym)
    for term in sp.Add.make_args(sp.expand(spec.H)):
        for i, x in enumerate(spec.xsym):
            if x in term.free_symbols:
                parts[i] += term
    return parts


class _C99(C99CodePrinter):
    """C99 printer writing small integer powers as products (pow() is a libm call)."""

    def _print_Pow(self, expr):
        base, exp = expr.as_base_exp()
        if exp.is_Integer and 2 <= abs(int(exp)) <= 4:
            product = "*".join([f"({self._print(base)})"] * abs(int(exp)))
            return f"({product})" if exp > 0 else f"(1.0/({product}))"
        return super()._print_Pow(expr)


class Printer:
    """C text for sympy expressions, with parameters read from r[] and CSE temporaries."""

    def __init__(self, spec):
        self.subs = {s: sp.Symbol(f"r[VR_{k}]") for k, s in spec.psym.items()}

    def arrays(self, **symbols):
        """Maps each state symbol to name[i] for every (name, symbols) pair."""
        for name, syms in symbols.items():
            self.subs.update({s: sp.Symbol(f"{name}[{i}]") for i, s in enumerate(syms)})

    def assign(self, targets, exprs):
        """Statements target_k = expr_k, sharing common subexpressions."""
        exprs = [sp.sympify(e).xreplace(self.subs) for e in exprs]
        temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"))
        c = _C99()
        lines = [f"    const double {t} = {c.doprint(v)};" for t, v in temps]
        lines += [f"    {t} = {c.doprint(e)};" for t, e in zip(targets, reduced)]
        return "\n".join(lines)


def _printer(spec, **arrays):
    """A Printer with the given state copies mapped to C arrays."""
    p = Printer(spec)
    p.arrays(**arrays)
    return p


def _state_copies(spec, tag):
    """Fresh symbols for one copy of the state (old x, new w, midpoint xm)."""
    return [sp.Symbol(f"{k}__{tag}", real=True) for k in spec.states]


def gen_energy(spec):
    """C function energy(r, x) = H(x)."""
    body = _printer(spec, x=spec.xsym).assign(["H"], [spec.H])
    return ("static double energy(const double *r, const double *x) {\n    double H;\n"
            f"{body}\n    return H;\n}}\n")


def _dgrad_body(spec, kind, x, xn, xm):
    """C statements writing z[i], the discrete gradient between x and xn."""
    n = len(spec.xsym)
    grad_m = [sp.diff(spec.H, s).xreplace(dict(zip(spec.xsym, xm))) for s in spec.xsym]
    pr = _printer(spec, x=x, w=xn, xm=xm)
    if kind == "quadratic":
        return pr.assign([f"z[{i}]" for i in range(n)], grad_m)
    if kind == "separable":
        quotients = dict(_quotients(spec, x, xn))
        plain = [i for i in range(n) if quotients.get(i, (0, 0))[1] is not None]
        exact = {i: poly for i, (_, poly) in quotients.items() if poly is not None}
        lines = [pr.assign([f"z[{i}]" for i in plain], [exact.get(i, grad_m[i]) for i in plain])]
        parts = _separable_parts(spec)
        for i, (raw, poly) in quotients.items():
            if poly is None:
                xi = spec.xsym[i]
                mean = _gauss_mean(sp.diff(parts[i], xi), xi, x[i], xn[i])
                lines.append(_branches(_near(spec, i), f"z[{i}]", pr, mean, raw))
        return "\n".join(lines)
    H = spec.H
    Hx, Hxn = H.xreplace(dict(zip(spec.xsym, x))), H.xreplace(dict(zip(spec.xsym, xn)))
    head = pr.assign(["dH"] + [f"z[{i}]" for i in range(n)], [Hxn - Hx] + grad_m)
    return (f"    double dH, d2 = 0.0, xx = 0.0, gd = 0.0;\n{head}\n"
            f"    for (int i = 0; i < NX; i++) {{\n        double d = w[i] - x[i];\n"
            f"        d2 += d * d; xx += x[i] * x[i] + w[i] * w[i]; gd += z[i] * d;\n    }}\n"
            f"    if (d2 > {SMALL_DELTA ** 2:g} * xx) {{\n        double k = (dH - gd) / d2;\n"
            f"        for (int i = 0; i < NX; i++) z[i] += k * (w[i] - x[i]);\n    }}")


def gen_dgrad(spec, kind):
    x, xn, xm = (_state_copies(spec, t) for t in ("x", "w", "xm"))
    body = _dgrad_body(spec, kind, x, xn, xm)
    return ("/* Discrete gradient z of H between x and w[0..NX-1], midpoint xm. */\n"
            "static void dgrad(const double *r, const double *x, const double *w, const double *xm, double *z) {\n"
            "    (void)r; (void)x; (void)w; (void)xm;\n"
            f"{body}\n}}\n")


def _structure(spec):
    """A = J - R, B = G - P, C = (G + P)^T, D = S + N as sympy matrices."""
    return spec.J - spec.R, spec.G - spec.P, (spec.G + spec.P).T, spec.S + spec.N


def gen_structure(spec):
    """C function structure(r, xm, A, B, C, D)."""
    xm = _state_copies(spec, "xm")
    rep = dict(zip(spec.xsym, xm))
    pr = _printer(spec, xm=xm)
    names, exprs = [], []
    for name, M in zip("ABCD", _structure(spec)):
        for i in range(M.rows):
            for k in range(M.cols):
                names.append(f"{name}[{i * M.cols + k}]")
                exprs.append(M[i, k].xreplace(rep))
    return ("/* A = J - R, B = G - P, C = (G + P)^T, D = S + N at the midpoint xm. */\n"
            "static void structure(const double *r, const double *xm, double *A, double *B, double *C, double *D) {\n"
            f"    (void)r; (void)xm;\n{pr.assign(names, exprs)}\n}}\n")


def _hz_entries(spec, xm):
    """d z / d x' as {(i, k): expr}: half the Hessian at xm (exact for the midpoint rule, the limit
    of the others as x' -> x; separable H gets the exact derivative of its quotients on top)."""
    n = len(spec.xsym)
    hess = sp.hessian(spec.H, spec.xsym).xreplace(dict(zip(spec.xsym, xm)))
    return {(i, k): hess[i, k] / 2 for i in range(n) for k in range(n) if hess[i, k] != 0}


def gen_jacobian_terms(spec, kind):
    """C function jacobian_terms: the pieces of the Newton matrix that depend on H and the state."""
    n, m = len(spec.xsym), len(spec.ports)
    x, xn, xm = (_state_copies(spec, t) for t in ("x", "w", "xm"))
    z = [sp.Symbol(f"z__{i}") for i in range(n)]
    u = [sp.Symbol(f"u__{j}") for j in range(m)]
    pr = _printer(spec, x=x, xm=xm, z=z)
    pr.subs.update({s: sp.Symbol(f"w[{i}]") for i, s in enumerate(xn)})
    pr.subs.update({s: sp.Symbol(f"w[{n + j}]") for j, s in enumerate(u)})
    A, B, C, D = (M.xreplace(dict(zip(spec.xsym, xm))) for M in _structure(spec))
    flow, out = A * sp.Matrix(z) + B * sp.Matrix(u), C * sp.Matrix(z) + D * sp.Matrix(u)
    names, exprs = [], []
    for (i, k), e in _hz_entries(spec, xm).items():
        names.append(f"Hz[{i * n + k}]")
        exprs.append(e)
    for label, vec in (("dA", flow), ("dC", out)):
        for i in range(vec.rows):
            for k in range(n):
                d = sp.diff(vec[i], xm[k]) / 2
                if d != 0:
                    names.append(f"{label}[{i * n + k}]")
                    exprs.append(d)
    body = pr.assign(names, exprs) if names else ""
    if kind == "separable":
        parts = _separable_parts(spec)
        for i, (raw, poly) in _quotients(spec, x, xn):
            if poly is not None:
                body += "\n" + pr.assign([f"Hz[{i * n + i}]"], [sp.diff(poly, xn[i])])
                continue
            xi = spec.xsym[i]
            exact = (sp.diff(parts[i], xi).subs(xi, xn[i]) - z[i]) / (xn[i] - x[i])
            mean = sp.diff(_gauss_mean(sp.diff(parts[i], xi), xi, x[i], xn[i]), xn[i])
            body += "\n" + _branches(_near(spec, i), f"Hz[{i * n + i}]", pr, mean, exact)
    return ("/* Hz = dz/dx', dA = d(A z + B u)/dx', dC = d(C z + D u)/dx' at fixed z, u. */\n"
            "static void jacobian_terms(const double *r, const double *x, const double *w, const double *xm,\n"
            "                           const double *z, double *Hz, double *dA, double *dC) {\n"
            "    (void)r; (void)x; (void)w; (void)xm; (void)z;\n"
            "    for (int k = 0; k < NX * NX; k++) Hz[k] = dA[k] = 0.0;\n"
            "    for (int k = 0; k < NU * NX; k++) dC[k] = 0.0;\n"
            f"{body}\n}}\n")


def gen_extra_outputs(spec):
    """C function extra_outputs(r): the spec's `outputs` from the current state."""
    names = [f"r[VR_{k}]" for k in spec.outputs]
    body = _printer(spec, x=spec.xsym).assign(names, [v[0] for v in spec.outputs.values()]) if names else ""
    reads = "".join(f"    x[{i}] = r[VR_{k}];\n" for i, k in enumerate(spec.states)) if names else ""
    decl = f"    double x[{len(spec.states)}];\n" if names else "    (void)r;\n"
    return f"static void extra_outputs(double *r) {{\n{decl}{reads}{body}\n}}\n"


def constant_structure(spec):
    """J, R, G, P, S, N free of the states."""
    return not any(M.free_symbols & set(spec.xsym) for M in _structure(spec))


def is_linear(spec, kind):
    """Quadratic H and constant structure: the step is an affine map."""
    return kind == "quadratic" and constant_structure(spec)


def model_c(spec):
    """The generated model.c: tables, generated functions, then the shared step."""
    kind = classify(spec)
    states = ", ".join(f"VR_{k}" for k in spec.states)
    effort = ", ".join("1" if p["effort_in"] else "0" for p in spec.ports)
    return "\n".join([
        f"/* Generated by fmus/codegen/ph.py from {spec.path.name}; discrete gradient: {kind}. Do not edit. */",
        "#include <math.h>", '#include "model.h"', "",
        "#define NX PH_NX", "#define NU PH_NU", f"#define LINEAR {int(is_linear(spec, kind))}",
        f"#define CONST_STRUCTURE {int(constant_structure(spec))}",
        f"static const int state_vr[NX] = {{{states}}};", f"static const int effort_in[NU] = {{{effort}}};", "",
        gen_energy(spec), gen_dgrad(spec, kind), gen_structure(spec), gen_jacobian_terms(spec, kind),
        gen_extra_outputs(spec), '#include "ph_step.h"', ""])


def _c_str(text):
    """A C string literal."""
    return '"' + str(text).replace("\\", "\\\\").replace('"', '\\"') + '"'


def _real(name, kind, start, unit, desc):
    """One row of REAL_VARIABLES."""
    return f"    X({name}, {kind}, {float(start)!r}, {_c_str(unit)}, {_c_str(desc)})"


def _real_rows(spec):
    """REAL_VARIABLES rows in the hand-written models' order: parameters, gamma, states, inputs,
    outputs, H."""
    d = spec.data
    gamma = d.get("gamma", 1.0)
    gamma = gamma if isinstance(gamma, list) else [gamma]
    rows = [_real(k, "PARAMETER", *v) for k, v in spec.params.items()]
    rows.append(_real("gamma", "TUNABLE", gamma[0], _pad(gamma[1:], 1)[0],
                      "scattering impedance of the wave ports"))
    rows += [_real(k, "STATE", *v) for k, v in spec.states.items()]
    for p in spec.ports:
        unit = p["effort_unit"] if p["effort_in"] else p["flow_unit"]
        rows.append(_real(f"a{p['suffix']}", "INPUT", 0.0, "sqrt(J)",
                          "incident wave (wave mode), scaled by sqrt(dt)"))
        rows.append(_real(p["input"], "INPUT", 0.0, unit, "physical port input (physical mode)"))
    for p in spec.ports:
        rows.append(_real(f"b{p['suffix']}", "OUTPUT", 0.0, "sqrt(J)", "outgoing wave, scaled by sqrt(dt)"))
        rows.append(_real(f"e{p['suffix']}", "OUTPUT", 0.0, p["effort_unit"], "port effort at the stage"))
        rows.append(_real(f"f{p['suffix']}", "OUTPUT", 0.0, p["flow_unit"], "port flow at the stage"))
    rows += [_real(k, "OUTPUT", 0.0, v[1], v[2]) for k, v in spec.outputs.items()]
    rows.append(_real("H", "OUTPUT", 0.0, d.get("energy_unit", "J"), "stored energy"))
    return rows


def config_h(spec):
    """The generated config.h: identifier, variable tables and port channels."""
    guid = spec.data.get("guid") or "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "wavecosim/" + spec.name)) + "}"
    channels = " \\\n".join(
        f"    X(a{p['suffix']}, b{p['suffix']}, e{p['suffix']}, f{p['suffix']}, {p['input']}, "
        f"{'EFFORT_INPUT' if p['effort_in'] else 'FLOW_INPUT'})" for p in spec.ports)
    return "\n".join([
        f"/* Generated by fmus/codegen/ph.py from {spec.path.name}. Do not edit. */",
        f"#define MODEL_IDENTIFIER {spec.name}", f"#define MODEL_GUID {_c_str(guid)}",
        f"#define MODEL_DESCRIPTION {_c_str(spec.data.get('description', spec.name))}", "",
        "#define REAL_VARIABLES(X) \\", " \\\n".join(_real_rows(spec)), "",
        "#define INTEGER_VARIABLES(X) \\",
        '    X(port_mode, 0, "0 = wave ports (inputs a*, outputs b*), 1 = physical ports") \\',
        '    X(newton_max_iter, 50, "Newton iterations allowed per step (one solve when linear)")', "",
        "#define PORT_CHANNELS(X) \\", channels, "", *cache_types(spec), ""])


def cache_types(spec):
    """Sizes, the structure matrices' type and, for a linear step, its cache kept in ModelData."""
    lines = [f"#define PH_NX {len(spec.states)}", f"#define PH_NU {len(spec.ports)}",
             "typedef struct {",
             "    double A[PH_NX * PH_NX], B[PH_NX * PH_NU], C[PH_NU * PH_NX], D[PH_NU * PH_NU];",
             "} PhStructure;"]
    if is_linear(spec, classify(spec)):
        lines += ["/* The affine step map (x, c) -> (x', u, y) for the step size h and closure slopes s. */",
                  "typedef struct {",
                  "    double h, s[PH_NU], T[(PH_NX + 2 * PH_NU) * (PH_NX + PH_NU + 1)];", "} PhCache;",
                  "#define MODEL_EXTRA_FIELDS PhCache ph;"]
    return lines


def generate(spec_path, out_dir) -> Path:
    """Writes config.h, model.c and ph_step.h for one spec into out_dir (files only when changed)."""
    spec = load(spec_path)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, text in (("config.h", config_h(spec)), ("model.c", model_c(spec)),
                       ("ph_step.h", STEP_HEADER.read_text())):
        target = out_dir / name
        if not target.exists() or target.read_text() != text:
            target.write_text(text)
    return out_dir


if __name__ == "__main__":
    try:
        generate(sys.argv[1], sys.argv[2])
    except ConfigError as exc:
        sys.exit(str(exc))
