"""What a stage is: the scene keys and artifacts it depends on, what it writes, how.

A stage reads its upstream stages' artifacts (files, never objects in memory) and writes
its own. Each output has an inputs hash: the hash of exactly the scene values, input
files and upstream artifacts it depends on. An output whose file carries the same hash is
current and is not recomputed. Figures are outputs too, drawn from artifacts only: a
missing or outdated figure is redrawn without recomputing anything.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable


@dataclass(frozen=True)
class Output:
    """One artifact of a stage. file: its name in the output folder. key: what tells it
    apart from the stage's other outputs (e.g. the contact treatment), part of its hash.
    depends: scene keys this output depends on beyond its stage's."""

    file: str
    key: str = ""
    depends: tuple[str, ...] = ()


@dataclass(frozen=True)
class Figure:
    """Figures drawn from artifacts.

    name: its entry in figures/manifest.json. files(scene): PNG names under figures/.
    depends: scene keys ("section" or "section.key") that change the picture.
    inputs(scene): artifact file names it reads; those that exist enter its hash.
    draw(ctx): draws them.
    """

    name: str
    files: Callable[[object], tuple[str, ...]]
    depends: tuple[str, ...]
    inputs: Callable[[object], tuple[str, ...]]
    draw: Callable[["Context"], None]


@dataclass(frozen=True)
class Estimate:
    """What computing some outputs of a stage will roughly cost (pipelines.guard).

    size: what drives the cost, in words ("~24 000 nodes"). memory: peak, bytes. seconds:
    wall time on a machine like the 2-core reference one. disk: bytes of the files written.
    advice: which scene key to change to make it smaller. scratch: bytes of temporary files
    the stage writes under TMPDIR (tempfile.gettempdir()) and removes when it ends;
    scratch_what: what they are; scratch_advice: the scene key that avoids them.
    """

    size: str
    memory: float
    seconds: float
    disk: float
    advice: str
    scratch: float = 0.0
    scratch_what: str = "temporary files"
    scratch_advice: str = ""


@dataclass(frozen=True)
class Background:
    """A stage computing ahead of its turn, beside the stage before it (Stage.start).

    lend(n): n more of the machine's cores for it (the stage before it ending processes).
    finish(): in its turn, waits for it and writes its outputs; raises what it raised.
    cancel(): ends it, writing nothing (the run stopped before its turn).
    status(): how far it is, a few words for the live line of the stage before it
    (e.g. "ti: 12/161 speeds")."""

    lend: Callable[[int], None]
    finish: Callable[[], None]
    cancel: Callable[[], None]
    status: Callable[[], str] = lambda: ""


@dataclass(frozen=True)
class Stage:
    """name. depends: scene keys ("section" or "section.key") its results depend on.
    upstream: stages whose artifacts it reads. outputs(scene): its Outputs.
    compute(ctx, outputs): computes and writes the given (not current) outputs.
    files(scene): input files that enter the hash by content, {label: path}.
    figures: the Figures drawn from its artifacts.
    estimate(scene, out, outputs): an Estimate of computing those outputs (None: cheap or
    unknown), for the size guard; `out` may hold current upstream artifacts to count from.
    distributed: under `mpirun -n N` (pipelines.parallel), compute runs on every rank and
        writes on rank 0 only; otherwise it runs on rank 0 alone while the others wait.
    start(ctx, outputs, cores): begins computing those outputs in the background on `cores`
        cores (0: none yet), beside the stage before it, and returns a Background; None:
        the stage computes in its turn only. The runner starts it when its upstream is
        current and the two fit the machine's memory, outside MPI runs.
    busy_cores(scene, outputs): how many cores compute keeps busy; a stage that has it
        hands the next stage's start (begun on no core) the cores it leaves free once its own
        processes are started, and each process's core as it ends (ctx.lend_cores); None: the
        next stage waits for this one. (Not before its processes are started: they are forked,
        and a fork while the stage beside writes HDF5 from a thread would copy HDF5's lock
        held into the child.)"""

    name: str
    depends: tuple[str, ...]
    upstream: tuple[str, ...]
    outputs: Callable[[object], tuple[Output, ...]]
    compute: Callable[["Context", tuple[Output, ...]], None]
    files: Callable[[object], dict] = lambda scene: {}
    figures: tuple[Figure, ...] = ()
    estimate: Callable[[object, Path, tuple[Output, ...]], "Estimate | None"] = lambda scene, out, outputs: None
    distributed: bool = False
    start: Callable[["Context", tuple[Output, ...], int], Background] | None = None
    busy_cores: Callable[[object, tuple[Output, ...]], int] | None = None


@dataclass
class Context:
    """What a stage's functions get. scene; out: the output folder; progress: the run's
    pipelines.progress.Progress; hashes: {file: inputs hash} and inputs: {file: {component:
    hash}} of the outputs being written (what write_artifact records). lend_cores(n): tells
    the stage started beside this one that n of this stage's cores are free (a no-op when
    none is); beside(): that stage's Background.status, for this stage's live line ("" when
    none is started)."""

    scene: object
    out: Path
    progress: object
    hashes: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    lend_cores: Callable[[int], None] = lambda n: None
    beside: Callable[[], str] = lambda: ""

    def provenance(self, output: Output, stage: str) -> dict:
        """Keyword arguments of write_artifact for `output` (stage, scene text, hashes)."""
        return {"stage": stage, "scene_text": self.scene.text, "inputs_hash": self.hashes[output.file],
                "extra_attrs": {"inputs": json.dumps(self.inputs[output.file], sort_keys=True)}}

    def attrs(self, output: Output, stage: str) -> dict:
        """Root attributes of a branch file (pipelines.branch_store) for `output`."""
        from pipelines import artifacts as art

        return {"stage": stage, "units": art.UNITS_SI, "scene": self.scene.text,
                "inputs_hash": self.hashes[output.file], "code_version": art.code_version(),
                "inputs": json.dumps(self.inputs[output.file], sort_keys=True)}

    def log(self, text: str) -> None:
        self.progress.log(text)
