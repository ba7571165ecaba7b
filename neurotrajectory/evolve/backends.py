"""Where the population is evaluated: in this process, in a pool of processes, or on Ray.

Every backend runs :class:`Worker` objects. A worker holds the current
:class:`~neurotrajectory.evolve.population.Population` and advances it from *recipes*
(parents and seeds, a few numbers per child), never from weight vectors; only a warm start
(its one fitted genome) and a resumed run (the checkpoint's population) ship weights, once.
Individuals are assigned to workers statically (``i % workers``) and each evaluation is
deterministic, so the results do not depend on the backend or the number of workers.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import signal
import threading
import warnings
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from gridsim.errors import DataWarning
from neurotrajectory.evolve.fitness import Evaluator, scenario_net_config
from neurotrajectory.evolve.genome import Recipe
from neurotrajectory.evolve.population import Population
from neurotrajectory.model import NetConfig, TrajectoryNet

BACKENDS = ("local", "processes", "ray")


#: What a worker that ended without answering (killed: by the out-of-memory killer?) says.
WORKER_DIED = (
    "a worker process died (killed, by the system's out-of-memory killer perhaps: "
    "fewer --workers or a smaller --batch need less memory); the run goes on with "
    "train --resume"
)


class BackendError(RuntimeError):
    """A backend could not be started or lost its workers."""


@dataclass(frozen=True)
class WorkerSpec:
    """Everything a worker needs to build its environments and network."""

    scenario: str
    overrides: dict
    net: NetConfig
    seeds: tuple[int, ...]  # the default episodes; each evaluation names its own
    batch: int = 16  # individuals evaluated together (batch * episodes environments)
    evolve: str = "all"  # what mutation changes (:data:`~neurotrajectory.model.EVOLVE_SCOPES`)
    #: the scenario overrides of validation episodes, if not ``overrides`` (other ego tracks)
    validation_overrides: dict | None = None


#: One individual's result: its index, mean fitness ``[l1, l2, l3]`` and episode statistics.
Evaluated = tuple[int, np.ndarray, dict]


@contextlib.contextmanager
def _data_checked() -> Iterator[None]:
    """Where a worker loads the scenario: its data warnings (skipped files, flawed tracks)
    were the trainer's to give when it checked the run, once, not again in every worker."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        yield


class Worker:
    """Holds the population and evaluates individuals."""

    def __init__(self, spec: WorkerSpec) -> None:
        self.spec = spec
        with _data_checked():
            self.evaluator = Evaluator(
                spec.scenario, spec.overrides, spec.net, list(spec.seeds), batch=spec.batch
            )
        self._validator: Evaluator | None = None
        self.population = Population(self.evaluator.net, spec.evolve)

    def _evaluator_for(self, validation: bool) -> Evaluator:
        """The evaluator of training episodes, or of validation episodes (made at first use
        when they have overrides of their own)."""
        spec = self.spec
        if not validation or spec.validation_overrides is None:
            return self.evaluator
        if self._validator is None:
            with _data_checked():
                self._validator = Evaluator(spec.scenario, spec.validation_overrides, spec.net,
                                            list(spec.seeds), batch=spec.batch)  # fmt: skip
        return self._validator

    @property
    def genome_size(self) -> int:
        return self.population.genome_size

    def advance(self, recipes: list[Recipe]) -> None:
        """Replace the population by the children of ``recipes``."""
        self.population.advance(recipes)

    def load(self, genomes) -> None:
        """Hold a copy of ``genomes`` as the population."""
        self.population.load(genomes)

    def evaluate(self, job: tuple[list[int], tuple[int, ...], bool]) -> list[Evaluated]:
        """Fitness and statistics of individuals ``indices`` on the episodes ``seeds``
        (``job = (indices, seeds, validation)``: validation episodes drive the spec's
        ``validation_overrides``), evaluated in batches (the result of each does not depend
        on the batches)."""
        indices, seeds, validation = job
        idx = np.asarray(indices, dtype=np.int64)
        if len(idx) == 0:
            return []
        step = int(idx[1] - idx[0]) if len(idx) > 1 else 1
        genomes = self.population.genomes
        if step > 0 and np.array_equal(idx, idx[0] + step * np.arange(len(idx))):
            rows = genomes[idx[0] : idx[-1] + 1 : step]  # a view, no copy
        else:
            rows = genomes[idx]
        results = self._evaluator_for(validation).evaluate_many(rows, seeds)
        return [(int(i), f, s.__dict__) for i, (f, s) in zip(idx, results, strict=True)]


class Backend(ABC):
    """Evaluates a population held by its workers."""

    #: The population as the trainer reads it (to checkpoint it): see the subclasses.
    population: Population

    @abstractmethod
    def advance(self, recipes: list[Recipe]) -> None:
        """Replace the population by the children of ``recipes``."""

    @abstractmethod
    def load(self, genomes: np.ndarray) -> None:
        """Replace the population by a copy of ``genomes``."""

    @abstractmethod
    def evaluate(
        self, size: int, seeds: tuple[int, ...], validation: bool = False
    ) -> tuple[np.ndarray, list[dict]]:
        """Fitness ``(size, 3)`` and per-individual episode statistics on the episodes
        ``seeds`` (``validation``: validation episodes, see :class:`WorkerSpec`)."""

    @abstractmethod
    def evaluate_members(
        self, indices: list[int], seeds: tuple[int, ...], validation: bool = False
    ) -> tuple[np.ndarray, list[dict]]:
        """Fitness ``(len(indices), 3)`` and episode statistics of the individuals
        ``indices`` (in that order) on the episodes ``seeds``; the ``j``-th goes to worker
        ``j % workers`` (an individual's result does not depend on where it runs)."""

    def close(self) -> None:  # noqa: B027 - optional
        pass


def _collect(size: int, parts: list[list[Evaluated]]):
    fitness = np.zeros((size, 3))
    stats: list[dict] = [{} for _ in range(size)]
    for part in parts:
        for i, f, s in part:
            fitness[i], stats[i] = f, s
    return fitness, stats


def _jobs(size: int, workers: int, seeds: tuple[int, ...], validation: bool) -> list:
    """Individual ``i`` goes to worker ``i % workers``; every worker runs the same episodes."""
    return [(list(range(k, size, workers)), tuple(seeds), validation) for k in range(workers)]


def _members(indices: list[int], parts: list[list[Evaluated]]):
    """The results of ``parts`` in the order of ``indices`` (no index twice)."""
    found = {i: (f, s) for part in parts for i, f, s in part}
    return (np.array([found[i][0] for i in indices]).reshape(len(indices), 3),
            [found[i][1] for i in indices])  # fmt: skip


def _check_members(indices: list[int]) -> list[int]:
    indices = [int(i) for i in indices]
    if len(set(indices)) != len(indices):
        raise BackendError(f"evaluate_members: an index twice in {indices}")
    return indices


class LocalBackend(Backend):
    """One worker in this process; its population is the trainer's (made once)."""

    def __init__(self, spec: WorkerSpec) -> None:
        self.worker = Worker(spec)
        self.population = self.worker.population

    def advance(self, recipes):
        self.worker.advance(recipes)

    def load(self, genomes):
        self.worker.load(genomes)

    def evaluate(self, size, seeds, validation=False):
        job = (list(range(size)), tuple(seeds), validation)
        return _collect(size, [self.worker.evaluate(job)])

    def evaluate_members(self, indices, seeds, validation=False):
        indices = _check_members(indices)
        return _members(indices, [self.worker.evaluate((indices, tuple(seeds), validation))])


def _serve(conn, spec: WorkerSpec) -> None:
    """Worker process loop: commands arrive as (name, argument) pairs. Ctrl-C and SIGTERM
    (sent to the whole process group by a terminal, a job scheduler or systemd) are the
    trainer's to handle (it stops the workers): a worker ignores them."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    warnings.simplefilter("ignore", DataWarning)  # the trainer's to give (see _data_checked)
    worker = Worker(spec)
    reply = ("ready", worker.genome_size)
    while True:
        try:  # the trainer may be gone (interrupted, failed): nothing to answer then
            _answer(conn, reply)
            name, arg = conn.recv()
        except (EOFError, OSError):
            return
        if name == "stop":
            return
        try:
            reply = ("ok", getattr(worker, name)(arg))
        except Exception as exc:  # report, do not die silently
            reply = ("error", f"{type(exc).__name__}: {exc}")


def _answer(conn, reply) -> None:
    """Send ``reply``; one that cannot be pickled becomes an error reply (pickling fails
    before anything is written)."""
    try:
        conn.send(reply)
    except (EOFError, OSError):
        raise
    except Exception as exc:
        conn.send(("error", f"cannot send the answer: {type(exc).__name__}: {exc}"))


class RemoteBackend(Backend):
    """Workers in other processes, each holding the population. The trainer keeps its own
    copy (:attr:`population`), advanced in step with theirs: checkpoints and the front need
    the weights, and fetching them back would ship the whole population every generation."""

    def __init__(self, spec: WorkerSpec, workers: int) -> None:
        if workers < 1:
            raise BackendError(f"workers must be >= 1, got {workers}")
        self.workers = workers
        net = TrajectoryNet(scenario_net_config(spec.scenario, spec.overrides, spec.net))
        self.population = Population(net, spec.evolve)

    @abstractmethod
    def _all(self, name: str, args: list) -> list:
        """Call :class:`Worker` method ``name`` on every worker (one argument each); their
        results."""

    def _shipped(self, genomes: np.ndarray):
        """``genomes`` as the workers receive them."""
        return genomes

    def advance(self, recipes):
        self._all("advance", [recipes] * self.workers)
        self.population.advance(recipes)

    def load(self, genomes):
        self._all("load", [self._shipped(genomes)] * self.workers)
        self.population.load(genomes)

    def evaluate(self, size, seeds, validation=False):
        jobs = _jobs(size, self.workers, seeds, validation)
        return _collect(size, self._all("evaluate", jobs))

    def evaluate_members(self, indices, seeds, validation=False):
        indices = _check_members(indices)
        jobs = [(indices[k :: self.workers], tuple(seeds), validation)
                for k in range(self.workers)]  # fmt: skip
        return _members(indices, self._all("evaluate", jobs))


class ProcessBackend(RemoteBackend):
    """``workers`` processes (spawned, so safe with torch), each holding the population."""

    def __init__(self, spec: WorkerSpec, workers: int) -> None:
        super().__init__(spec, workers)
        ctx = mp.get_context("spawn")
        self.conns, self.procs = [], []
        self._waiting = False  # for the workers' answers to a command (see close)
        with _sigint_ignored():  # from their start on (an ignored signal stays so in the child)
            for _ in range(workers):
                parent, child = ctx.Pipe()
                proc = ctx.Process(target=_serve, args=(child, spec), daemon=True)
                proc.start()
                child.close()  # the worker's end: a worker that dies ends our recv with EOF
                self.conns.append(parent)
                self.procs.append(proc)
        self._waiting = True
        try:
            for conn in self.conns:
                self._reply(conn)
        except BaseException:  # interrupted or failed while they start: none is left behind
            self.close()
            raise
        self._waiting = False

    def _reply(self, conn):
        try:
            status, value = conn.recv()
        except (EOFError, ConnectionResetError):
            raise BackendError(WORKER_DIED) from None
        if status == "error":
            raise BackendError(f"worker failed: {value}")
        return value

    def _all(self, name, args):
        self._waiting = True
        for conn, arg in zip(self.conns, args, strict=True):
            try:
                conn.send((name, arg))
            except (BrokenPipeError, ConnectionResetError):  # (it died between commands)
                raise BackendError(WORKER_DIED) from None
        replies = [self._reply(conn) for conn in self.conns]
        self._waiting = False
        return replies

    def close(self):
        """Stop the workers: at once if a command's answers were still awaited (the trainer
        was interrupted or failed meanwhile: the workers would first finish it), else after
        they read ``stop``."""
        for conn, proc in zip(self.conns, self.procs, strict=True):
            if self._waiting:
                proc.kill()  # (a worker ignores SIGTERM: see _serve)
            else:
                with contextlib.suppress(BrokenPipeError, OSError):
                    conn.send(("stop", None))
            proc.join(timeout=10)
            if proc.is_alive():
                proc.kill()


@contextlib.contextmanager
def _sigint_ignored():
    """Ctrl-C ignored in the block, when called from the main thread (the only one that may
    set signal handlers; elsewhere the block runs as it is)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:  # None: a handler set outside Python, which Python cannot set back
        signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)


def _check_reachable(address: str, timeout: float = 3.0) -> None:
    """Fail fast (instead of Ray's long retries) when ``host:port`` does not answer."""
    import socket

    hostport = address.split("://", 1)[-1]
    host, _, port = hostport.rpartition(":")
    try:
        with socket.create_connection((host or "127.0.0.1", int(port)), timeout=timeout):
            pass
    except (OSError, ValueError) as exc:
        raise BackendError(f"cannot connect to Ray at {address}: {exc}") from None


class RayBackend(RemoteBackend):
    """``workers`` Ray actors on an existing cluster (``address``) or a local one."""

    def __init__(self, spec: WorkerSpec, workers: int, address: str | None = None) -> None:
        super().__init__(spec, workers)
        try:
            import ray
        except ImportError:
            raise BackendError("the ray backend needs Ray: pip install '.[ray]'") from None
        self.ray = ray
        if address and address != "auto":
            _check_reachable(address)
        try:
            if not ray.is_initialized():
                ray.init(address=address, num_cpus=None if address else workers,
                         include_dashboard=False, log_to_driver=False)  # fmt: skip
        except Exception as exc:
            where = address or "a local Ray instance"
            raise BackendError(f"cannot connect to Ray at {where}: {exc}") from None
        actor = ray.remote(num_cpus=1)(Worker)
        self.actors = [actor.remote(spec) for _ in range(workers)]

    def _all(self, name, args):
        return self.ray.get(
            [getattr(a, name).remote(arg) for a, arg in zip(self.actors, args, strict=True)]
        )

    def _shipped(self, genomes):
        return self.ray.put(genomes)  # once to the object store, not once per actor

    def close(self):
        for a in self.actors:
            self.ray.kill(a)


def make_backend(name: str, spec: WorkerSpec, workers: int, address: str | None = None) -> Backend:
    factories = {
        "local": lambda: LocalBackend(spec),
        "processes": lambda: ProcessBackend(spec, workers),
        "ray": lambda: RayBackend(spec, workers, address),
    }
    if name not in factories:
        raise BackendError(f"unknown backend {name!r}; choose from {sorted(factories)}")
    return factories[name]()
