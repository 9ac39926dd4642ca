"""Power bonds: two opposite connections between the halves of two ports (an output of one into
the input of the other, and back) become one coupling instead of two signals.

Port variables are oriented (README, physical ports): power into an FMU = sign * effort * flow.
With the connections e_in = c_e e_out and f_in = c_f f_out (c = +-1, no offset), the coupling is
equal_effort_opposite_flow when c_e = 1 (one_junction when c_e = -1) and the signs must satisfy
s_B = -c_e c_f s_A. A sign known on one side (our wave ports have +1, a port may declare one) gives
the other: so a factor -1 on such a connection becomes a port sign. Signs nothing fixes are left
to the run's probe."""
from dataclasses import dataclass

from ...errors import ConfigError
from .xmlfile import at, fail


@dataclass
class Signal:
    source: tuple          # (subsystem, variable)
    target: tuple
    factor: float
    offset: float
    elements: list         # the connections it passes, outermost last
    file: object = None    # the file of those elements when it is not the SSD (OspSystemStructure.xml)


def as_list(value):
    return [] if value is None else list(value) if isinstance(value, list) else [value]


def channels(port):
    """[(input variable, output variable, input kind)] of a declared port."""
    ins, kinds = as_list(port.get("physical_in")), as_list(port.get("input"))
    outs = as_list(port.get("physical_out")) or [
        as_list(port.get("effort", "e") if k == "flow" else port.get("flow", "f"))[j] for j, k in enumerate(kinds)]
    return list(zip(ins, outs, kinds)) if len(ins) == len(kinds) == len(outs) else []


def find_bonds(path, ports, signals):
    """Split signals into bond halves and plain signals: ({(A, j): (B, k, signal into A j)}, rest)."""
    ins = {(name, i): (name, j) for name, p in ports.items() for j, (i, _, _) in enumerate(channels(p))}
    outs = {(name, o): (name, j) for name, p in ports.items() for j, (_, o, _) in enumerate(channels(p))}
    halves, rest = {}, []
    for s in signals:
        if s.target not in ins:
            rest.append(s)
            continue
        if s.source not in outs or outs[s.source][0] == s.target[0]:
            fail(s.file or path, s.elements[0], f"the port input {'.'.join(s.target)} is driven by "
                                      f"{'.'.join(s.source)}, which is not the output of another port")
        halves[ins[s.target]] = (*outs[s.source], s)
    for (a, j), (b, k, s) in halves.items():
        back = halves.get((b, k))
        if back is None or back[:2] != (a, j):
            fail(s.file or path, s.elements[0], f"only one half of a power bond: {'.'.join(s.source)} -> "
                                      f"{'.'.join(s.target)}, but {b}'s port input is not driven by {a}'s port output")
    for name, p in ports.items():
        for j, (i, _, _) in enumerate(channels(p)):
            if (name, j) not in halves:
                raise_unbonded(path, name, i)
    return halves, rest


def where(path, signal):
    """`file line N` of the connection a signal comes from."""
    return at(signal.file or path, signal.elements[0])


def raise_unbonded(path, name, variable):
    raise ConfigError(f"{path.name}: the port of {name} (input {variable}) is connected to no other port")


def _factors(path, ports, halves, a, j):
    """(c_e, c_f, effort connection) of the bond at channel (a, j)."""
    b, k, into_a = halves[(a, j)]
    into_b = halves[(b, k)][2]
    kind_a = channels(ports[a])[j][2]
    if kind_a == channels(ports[b])[k][2]:
        fail(into_a.file or path, into_a.elements[0], f"{a} and {b} both take the {kind_a} as input: "
                                                      "not a power bond")
    effort, flow = (into_a, into_b) if kind_a == "effort" else (into_b, into_a)
    for s in (effort, flow):
        if abs(s.factor) != 1.0 or s.offset != 0.0:
            fail(s.file or path, s.elements[0], f"a power-bond connection must have factor 1 or -1 and "
                                                f"offset 0, got factor {s.factor:g}, offset {s.offset:g}")
    return effort.factor, flow.factor, effort


def couplings(path, ports, halves, fixed):
    """The couplings of the bonds, effort-output side first, and every channel's sign: {(A, j): +-1}
    from `fixed` (known signs) through the relation s_B = -c_e c_f s_A."""
    signs, out, done = dict(fixed), [], set()
    for (a, j) in sorted(halves, key=lambda n: list(ports).index(n[0])):
        b, k, _ = halves[(a, j)]
        if (a, j) in done:
            continue
        done |= {(a, j), (b, k)}
        c_e, c_f, effort = _factors(path, ports, halves, a, j)
        first, second = ((a, j), (b, k)) if channels(ports[a])[j][2] == "flow" else ((b, k), (a, j))
        out.append({"type": "equal_effort_opposite_flow" if c_e == 1 else "one_junction",
                    "ports": [first, second], "relation": -c_e * c_f, "where": where(path, effort)})
    _propagate(out, signs)
    return _merge_channels(out, ports), signs


def _propagate(bonds, signs):
    """Fill in signs across the bonds until nothing changes; a contradiction names the bond."""
    changed = True
    while changed:
        changed = False
        for bond in bonds:
            (x, y), rel = bond["ports"], bond["relation"]
            for p, other in ((x, y), (y, x)):
                if p in signs and other not in signs:
                    signs[other], changed = rel * signs[p], True
                elif p in signs and signs[other] != rel * signs[p]:
                    raise ConfigError(f"{bond['where']}: the factors of this power bond need "
                                      f"sign({other[0]}) = {rel:+g} * sign({p[0]}), but they are "
                                      f"{signs[other]:+g} and {signs[p]:+g}")


def _merge_channels(bonds, ports):
    """One coupling per pair of subsystems whose channels meet in order, else one per channel."""
    by_pair = {}
    for bond in bonds:
        by_pair.setdefault((bond["ports"][0][0], bond["ports"][1][0], bond["type"]), []).append(bond)
    out = []
    for (a, b, kind), group in by_pair.items():
        whole = all(x[1] == y[1] for x, y in (g["ports"] for g in group)) and \
            len(group) == len(channels(ports[a])) == len(channels(ports[b]))
        if whole and (kind == "equal_effort_opposite_flow" or len(group) == 1):
            out.append({"type": kind, "ports": [a, b]})
            continue
        out.extend({"type": kind, "ports": [f"{n}[{c}]" for n, c in g["ports"]]} for g in group)
    return out
