"""One DR run whose subsystems live in other processes (docs/parallel.md): a prototype.

A `SubsystemHost` opens its subsystems where it runs (FMU handles cannot cross processes: only the
scenario, plain data, travels) and answers three calls per macro-step: query (S_i^n, eq. 13,
frozen at x_i^n on the step's first call), advance (the commit, eq. 21, then the recorded outputs)
and read. The master process keeps Algorithm 1's arithmetic (masters/dr.py, algorithm1) and the
committed waves; so the numbers are those of the in-process run (energy guard off, no
certificates) to the last bit. Two engines carry the calls:
  shm   worker processes started with spawn (never fork after the kernel's threads started), the
        waves in one shared-memory block, a POSIX semaphore per worker to start a round and one to
        end it: the lowest round trip measured here, one machine;
  dask  Dask actors (`distributed`), one per worker of a Dask cluster, on any machine the cluster
        reaches; a round trip costs about a millisecond or more.
Not carried over (the prototype refuses them): signals and signal-only subsystems, substeps, gamma tuning,
the energy guards and certificates, deadlines.
"""
import multiprocessing
import time
from dataclasses import dataclass

import numpy as np

from ..core import interconnection as ic
from ..core.gamma import initial_gammas
from ..core.scene import coupling_structure, open_subsystems
from ..errors import ConfigError, WavecosimError
from ..masters.dr import algorithm1
from ..masters.dr_options import resolve_start
from .runner import grid_clock

ENGINES = ("shm", "dask")
STOP, QUERY, ADVANCE, READ, PING = range(5)
HEADER = 3                      # op, n, t at the start of the shared block


class SubsystemHost:
    """Some of a scene's subsystems, opened in this process: the calls of one macro-step on them."""

    def __init__(self, scenario, names):
        self.subsystems = open_subsystems(scenario, set(names))
        by_name = {s.name: s for s in self.subsystems}
        self.outputs = [(k, ref.split(".", 1)) for k, ref in enumerate(scenario.outputs.values())
                        if ref.split(".", 1)[0] in by_name]
        self._readers = [by_name[name].reader([var])[0] for _, (name, var) in self.outputs]
        self._step = None

    def ports(self):
        """[(name, channels)] of the subsystems hosted, in scenario order."""
        return [(s.name, s.m) for s in self.subsystems]

    def output_columns(self):
        """The indices of the recorded output columns these subsystems give."""
        return [k for k, _ in self.outputs]

    def _freeze(self, n, t):
        if self._step != n:
            for s in self.subsystems:
                s.freeze(n, t)
            self._step = n

    def _each(self, call, values):
        out, at = [], 0
        for s in self.subsystems:
            out.extend(call(s, list(values[at:at + s.m])))
            at += s.m
        return out

    def query(self, n, t, u):
        """S_i^n(u_i) of every subsystem hosted (stacked), x_i^n saved on the step's first call."""
        self._freeze(n, t)
        return self._each(lambda s, u_i: s.query(u_i), u)

    def advance(self, n, t, a):
        """The commit with a_i; (b^{n+1} stacked, the recorded outputs after it)."""
        self._freeze(n, t)
        return self._each(lambda s, a_i: s.advance(a_i), a), self.read()

    def read(self):
        return [read()[0] for read in self._readers]

    def ping(self):
        return 0

    def close(self):
        for s in self.subsystems:
            s.close()
        self.subsystems = []


@dataclass
class DistributedRun:
    """What a run in worker processes gives: times t (steps + 1), the recorded outputs (one row per
    time, scenario.outputs' columns), inner iterations per step, and the round trip of the engine
    (µs per call of every worker with no work, measured before the run)."""
    t: np.ndarray
    outputs: np.ndarray
    columns: list
    iterations: np.ndarray
    engine: str
    workers: int
    round_trip_us: float


class Hosts:
    """The workers of one run, whatever the engine: `call(op, n, t, values)` makes every worker's
    part of one round (values: the stacked inputs) and returns (stacked outputs, readings)."""
    engine = None

    def __init__(self, groups):
        self.groups = groups
        self.offsets = self.sizes = self.columns = None

    def layout(self, ports, columns):
        """Each worker's channels [(offset, m)] and output columns, from what the workers opened."""
        names = [name for group in ports for name, _ in group]
        at, self.sizes, self.offsets = 0, [], []
        for group in ports:
            m = sum(k for _, k in group)
            self.offsets.append(at)
            self.sizes.append(m)
            at += m
        self.columns = columns
        return names, [k for group in ports for _, k in group]

    def round_trip_us(self, rounds=200):
        """µs per round of every worker doing nothing (the engine's cost of one inner iteration)."""
        self.call(PING, 0, 0.0, None)
        started = time.perf_counter()
        for _ in range(rounds):
            self.call(PING, 0, 0.0, None)
        return 1e6 * (time.perf_counter() - started) / rounds


def _worker_loop(scenario, names, conn, go, done):
    """A spawned worker: open the subsystems, report their ports, then serve rounds from the shared block."""
    from multiprocessing import shared_memory
    try:
        host = SubsystemHost(scenario, names)
    except BaseException as exc:          # reported to the master, which raises it
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    try:
        conn.send(("ports", host.ports(), host.output_columns()))
        block_name, size, offset, m, n_out = conn.recv()
    except EOFError:                      # the master gave up (another worker failed to open)
        host.close()
        return
    block = shared_memory.SharedMemory(name=block_name)
    try:
        _serve(host, np.ndarray((size,), dtype=np.float64, buffer=block.buf), conn, go, done, offset, m, n_out)
    finally:
        host.close()
        block.close()


def _serve(host, shared, conn, go, done, offset, m, n_out):
    n_ch = (len(shared) - HEADER - n_out) // 2
    inputs, outputs = shared[HEADER + offset:HEADER + offset + m], shared[HEADER + n_ch + offset:][:m]
    readings = shared[HEADER + 2 * n_ch:]
    columns = host.output_columns()
    while True:
        go.acquire()
        op, n, t = int(shared[0]), int(shared[1]), float(shared[2])
        if op == STOP:
            return
        try:
            if op == QUERY:
                outputs[:] = host.query(n, t, inputs)
            elif op == ADVANCE:
                outputs[:], values = host.advance(n, t, inputs)
                readings[columns] = values
            elif op == READ:
                readings[columns] = host.read()
        except Exception as exc:              # reported to the master, which raises it
            conn.send(("error", str(exc) if isinstance(exc, WavecosimError) else f"{type(exc).__name__}: {exc}"))
        done.release()


class ShmHosts(Hosts):
    """Workers started with spawn; the round's data in one shared-memory block."""
    engine = "shm"

    def __init__(self, scenario, groups):
        from multiprocessing import shared_memory
        super().__init__(groups)
        ctx = multiprocessing.get_context("spawn")
        self.go = [ctx.Semaphore(0) for _ in groups]
        self.done = ctx.Semaphore(0)
        pipes = [ctx.Pipe() for _ in groups]
        self.conns = [a for a, _ in pipes]
        self.procs = [ctx.Process(target=_worker_loop, args=(scenario, names, b, go, self.done), daemon=True)
                      for names, (_, b), go in zip(groups, pipes, self.go)]
        self.block = None
        for p, (_, b) in zip(self.procs, pipes):
            p.start()
            b.close()                     # the worker's end: a worker that dies is then seen as EOF
        try:
            answers = [self._answer(c) for c in self.conns]
            self.names, self.m = self.layout([a[1] for a in answers], [a[2] for a in answers])
            n_ch, n_out = sum(self.sizes), len(scenario.outputs)
            size = HEADER + 2 * n_ch + n_out
            self.block = shared_memory.SharedMemory(create=True, size=8 * size)
            self.shared = np.ndarray((size,), dtype=np.float64, buffer=self.block.buf)
            self.shared[:] = 0.0
            self.inputs, self.outputs = self.shared[HEADER:HEADER + n_ch], self.shared[HEADER + n_ch:HEADER + 2 * n_ch]
            self.readings = self.shared[HEADER + 2 * n_ch:]
            for conn, offset, m in zip(self.conns, self.offsets, self.sizes):
                conn.send((self.block.name, size, offset, m, n_out))
        except BaseException:
            self.close()
            raise

    @staticmethod
    def _answer(conn):
        try:
            answer = conn.recv()
        except EOFError:
            raise WavecosimError("a worker process ended while it opened its subsystems") from None
        if answer[0] == "error":
            raise ConfigError(f"a worker could not open its subsystems: {answer[1]}")
        return answer

    def call(self, op, n, t, values):
        if values is not None:
            self.inputs[:] = values
        self.shared[:HEADER] = (op, n, t)
        for go in self.go:
            go.release()
        for _ in self.go:
            while not self.done.acquire(timeout=1.0):
                dead = [p.exitcode for p in self.procs if not p.is_alive()]
                if dead:
                    raise WavecosimError(f"a worker process ended (exit code {dead[0]}) in the middle of a round")
        for conn in self.conns:
            if conn.poll():
                raise WavecosimError(f"a worker failed: {conn.recv()[1]}")
        return list(self.outputs), self.readings

    def close(self):
        if self.block is not None:
            self.shared[0] = STOP
            for go in self.go:
                go.release()
        for conn in self.conns:
            conn.close()                  # a worker still waiting for its layout sees EOF and ends
        for p in self.procs:
            p.join(timeout=10)
            if p.is_alive():
                p.terminate()
        if self.block is not None:
            del self.shared, self.inputs, self.outputs, self.readings
            self.block.close()
            self.block.unlink()
            self.block = None


class DaskHosts(Hosts):
    """One Dask actor per group, each pinned to a worker of the client's cluster."""
    engine = "dask"

    def __init__(self, scenario, groups, client):
        super().__init__(groups)
        workers = list(client.scheduler_info()["workers"])
        if len(workers) < len(groups):
            raise ConfigError(f"the Dask cluster has {len(workers)} workers for {len(groups)} groups of subsystems")
        self.actors = [client.submit(SubsystemHost, scenario, names, actor=True, workers=[w]).result()
                       for names, w in zip(groups, workers)]
        ports = [a.ports().result() for a in self.actors]
        columns = [a.output_columns().result() for a in self.actors]
        self.names, self.m = self.layout(ports, columns)
        self.readings = np.zeros(len(scenario.outputs))

    def call(self, op, n, t, values):
        if op == PING:
            [f.result() for f in [a.ping() for a in self.actors]]
            return None, None
        if op == READ:
            for cols, f in zip(self.columns, [a.read() for a in self.actors]):
                self.readings[cols] = f.result()
            return None, self.readings
        parts = [values[o:o + m] for o, m in zip(self.offsets, self.sizes)]
        method = "query" if op == QUERY else "advance"
        futures = [getattr(a, method)(n, t, list(p)) for a, p in zip(self.actors, parts)]
        out = []
        for cols, f in zip(self.columns, futures):
            got = f.result()
            if op == ADVANCE:
                got, self.readings[cols] = got
            out.extend(got)
        return out, self.readings

    def close(self):
        for a in self.actors:
            a.close().result()
        self.actors = []


def _check(scenario):
    """What the prototype carries over; a ConfigError naming the rest."""
    if scenario.signals or scenario.signal_subsystems:
        raise ConfigError(f"{scenario.source}: signals are not carried over to worker processes yet")
    multi = next((s for s in scenario.subsystems if s.substeps != 1), None)
    if multi is not None:
        raise ConfigError(f"{scenario.source}: subsystems.{multi.name}.substeps: worker processes make one doStep "
                          f"per macro-step")
    if isinstance(scenario.gamma, str):
        raise ConfigError(f"{scenario.source}: gamma: {scenario.gamma} is not carried over to worker processes yet")
    m = scenario.master
    if m.algorithm != "dr":
        raise ConfigError(f"{scenario.source}: master.algorithm: worker processes run dr only")
    if (m.relaxation, m.anderson, resolve_start(m.start, m.energy_guard or "ledger"), m.deadline_us) != (1.0, 0, "paper", None):
        raise ConfigError(f"{scenario.source}: master: worker processes run Algorithm 1 as the paper gives it "
                          f"(no relaxation, anderson, start other than paper, or deadline_us yet)")


def groups_of(scenario, workers):
    """The subsystems in `workers` groups of consecutive subsystems (one each when workers is None)."""
    names = [s.name for s in scenario.subsystems]
    workers = len(names) if workers is None else max(1, min(int(workers), len(names)))
    return [names[len(names) * k // workers:len(names) * (k + 1) // workers] for k in range(workers)]


def open_hosts(scenario, engine="shm", workers=None, client=None):
    """The workers of a run, their subsystems opened (engine: shm, or dask with a distributed.Client)."""
    _check(scenario)
    groups = groups_of(scenario, workers)
    if engine == "shm":
        return ShmHosts(scenario, groups)
    if engine == "dask":
        if client is None:
            raise ConfigError("engine dask needs a distributed.Client")
        return DaskHosts(scenario, groups, client)
    raise ConfigError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")


def run_distributed(scenario, engine="shm", workers=None, client=None) -> DistributedRun:
    """Algorithm 1 over subsystems hosted by `workers` processes (one per subsystem by default)."""
    hosts = open_hosts(scenario, engine, workers, client)
    try:
        round_trip = hosts.round_trip_us()
        return _steps(scenario, hosts, round_trip)
    finally:
        hosts.close()


def _steps(scenario, hosts, round_trip):
    """The macro-steps of the run: algorithm1 in this process, S and the commit in the workers."""
    order = [s.name for s in scenario.subsystems]
    if hosts.names != order:
        raise ConfigError(f"{scenario.source}: the workers hold {hosts.names}, not the scenario's {order}")
    E, F, _ = coupling_structure(scenario, hosts.m)
    gammas = initial_gammas(scenario)
    coupling = ic.compile_wave_map(E, F, [gammas[name] for name, m in zip(order, hosts.m) for _ in range(m)],
                                   where=f"{scenario.source}: couplings")
    P, J_L = coupling.P_sparse, coupling.J_L_sparse
    K, eps, dt = scenario.master.K, scenario.master.eps, scenario.dt
    steps = scenario.n_steps
    rows = np.empty((steps + 1, len(scenario.outputs)))
    rows[0] = hosts.call(READ, 0, 0.0, None)[1]
    iterations = np.zeros(steps, dtype=int)
    b = [0.0] * sum(hosts.m)
    for n in range(steps):
        t = n * dt

        def S(u):
            return hosts.call(QUERY, n, t, u)[0]
        log = algorithm1(S, P, J_L, b, K, eps)
        b, readings = hosts.call(ADVANCE, n, t, log.a_hat)
        rows[n + 1], iterations[n] = readings, log.iterations
    clock = grid_clock(dt)
    return DistributedRun(np.array([clock(k) for k in range(steps + 1)]), rows, list(scenario.outputs), iterations, hosts.engine,
                          len(hosts.groups), round_trip)


def round_trips(scenario, engine="shm", workers=(1, 2, 8), client_for=None, rounds=200):
    """{workers: µs per round trip} of an engine on a scene's subsystems (client_for(w) gives a
    distributed.Client of w workers for dask)."""
    out = {}
    for w in workers:
        client = client_for(w) if client_for is not None else None
        try:
            hosts = open_hosts(scenario, engine, w, client)
            try:
                out[w] = hosts.round_trip_us(rounds)
            finally:
                hosts.close()
        finally:
            if client is not None:
                client.close()
    return out
