"""Every scene key a stage's computation or a figure's drawing reads is one its declared
dependencies cover, found by running it on a scene that records what is read (not from the
declared lists): a key read but not covered leaves a changed scene silently served the
results of the old one.

Covered: the stage's or figure's `depends` ("section", "section.key", "section~key"), its
output's, and the keys carried by the artifacts it reads that its own stage or one upstream
of it writes (brought up to date in every run that computes or draws it; not ti.h5 for the
NFRC figure, which a run `--until hbm` draws beside an old sweep). Not results: the scene's
text (the provenance every artifact records) and its path (files enter by content).
"""
import dataclasses
import threading
from pathlib import Path

import pytest

from coarse_runs import clone
from pipelines.progress import Progress
from pipelines.runner import expected_inputs, figure_hash, update_figures
from pipelines.scene import SECTIONS, load_scene
from pipelines.stages import REGISTRY, STAGES
from pipelines.stages.base import Context

#: Scene fields whose value no result holds (module docstring).
NOT_RESULTS = {"text", "path"}
#: Keys a stage reads for its log only: {stage: {key: why}}.
LOGGED = {"rom": {"contact.mu": "the friction-lock verdict for the scene's mu; rom.h5's table does not depend on mu"}}


class _Reads:
    """The keys read through recording scenes ("section.key", or a scene-level name)."""

    def __init__(self):
        self.keys: set[str] = set()
        self.paused = threading.local()

    def add(self, key: str) -> None:
        if not getattr(self.paused, "on", False):
            self.keys.add(key)

    def quiet(self, fn, *args):
        """fn(*args) without recording: hashing and comparing read every field, no result does."""
        self.paused.on = True
        try:
            return fn(*args)
        finally:
            self.paused.on = False


def _plain(base, items):
    """A pickled recording section comes back as the plain dataclass (to a worker process)."""
    return base(**dict(items))


def _recording_class(base, prefix: str, reads: _Reads):
    """A subclass of the frozen dataclass `base` whose field reads add "prefix.field" (a
    scene-level property, such as fixed_interface_modes, adds its own name only)."""
    fields = {f.name for f in dataclasses.fields(base)}
    properties = {n for n in dir(base) if isinstance(getattr(base, n, None), property)}

    def get(self, name):
        if name in fields:
            reads.add(f"{prefix}.{name}" if prefix else name)
        elif not prefix and name in properties:
            reads.add(name)
            return reads.quiet(object.__getattribute__, self, name)
        return object.__getattribute__(self, name)

    def reduce(self):  # sent whole to a process: every field counts as read
        return _plain, (base, tuple((f, getattr(self, f)) for f in fields))

    return type(f"Recording{base.__name__}", (base,), {
        "__getattribute__": get, "__reduce__": reduce,
        "__hash__": lambda self: reads.quiet(base.__hash__, self),
        "__eq__": lambda self, other: reads.quiet(base.__eq__, self, other),
        "__repr__": lambda self: reads.quiet(base.__repr__, self)})


def _recording(obj, prefix: str, reads: _Reads):
    new = object.__new__(_recording_class(type(obj), prefix, reads))
    for f in dataclasses.fields(obj):
        object.__setattr__(new, f.name, getattr(obj, f.name))
    return new


def recording_scene(scene):
    """(scene whose reads are recorded, its _Reads)."""
    reads = _Reads()
    new = _recording(scene, "", reads)
    for name in SECTIONS:
        object.__setattr__(new, name, _recording(getattr(scene, name), name, reads))
    reads.keys.clear()
    return new, reads


def result_keys(reads: _Reads) -> set[str]:
    """The recorded keys that may change a result: a section's fields (the bare section name
    is only the access to it) and scene-level names but NOT_RESULTS."""
    return {k for k in reads.keys if k not in SECTIONS and k not in NOT_RESULTS}


def covers(declared, key: str) -> bool:
    """Whether a declared dependency ("section", "section.key", "section~a~b", "name")
    covers the read key."""
    section, _, field = key.partition(".")
    for d in declared:
        name, *dropped = d.split("~")
        if d == key or ("." not in d and field and name == section and field not in dropped):
            return True
    return False


def _upstream_closure(name: str) -> list[str]:
    """The stage and every stage upstream of it."""
    out = [name]
    for up in REGISTRY[name].upstream:
        out += [s for s in _upstream_closure(up) if s not in out]
    return out


def carried(scene, stage: str) -> list[str]:
    """The scene keys carried by the artifacts of `stage` and its upstream stages (their
    outputs' inputs hashes enter the hashes of what reads them)."""
    keys = []
    for name in _upstream_closure(stage):
        s = REGISTRY[name]
        keys += list(s.depends) + [k for o in s.outputs(scene) for k in o.depends]
    return keys


def carried_to_figure(scene, stage: str, fig) -> list[str]:
    """The scene keys carried by the figure's inputs that its stage or one upstream of it
    writes (each with what its own upstream carries)."""
    keys = []
    for name in _upstream_closure(stage):
        s = REGISTRY[name]
        for o in s.outputs(scene):
            if o.file in fig.inputs(scene):
                keys += list(s.depends + o.depends) + [k for up in s.upstream for k in carried(scene, up)]
    return keys


def _uncovered(reads: _Reads, declared) -> list[str]:
    return sorted(k for k in result_keys(reads) if not covers(declared, k))


def _stage_of(figure: str) -> str:
    return next(s for s in STAGES for f in REGISTRY[s].figures if f.name == figure)


def test_the_recording_scene_and_the_cover_rule():
    """The reference itself: reads are recorded field by field, through dataclasses.replace
    and pickling; "~" excludes exactly the named keys."""
    import pickle

    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    scene, reads = recording_scene(load_scene(base))
    assert scene.contact.mu == 0.15 and reads.keys == {"contact", "contact.mu"}
    hash(scene)
    assert scene.fixed_interface_modes == 12 and result_keys(reads) == {"contact.mu", "fixed_interface_modes"}
    reads.keys.clear()
    pickle.loads(pickle.dumps(scene.casing))
    assert result_keys(reads) == {f"casing.{f.name}" for f in dataclasses.fields(scene.casing)}
    assert covers(("hbm~methods",), "hbm.n_time") and not covers(("hbm~methods",), "hbm.methods")
    assert covers(("name",), "name") and not covers(("contact.mu",), "contact.kappa")


@pytest.mark.parametrize("figure", ["nfrc", "hbm_vtu", "modes_vtu"])
def test_every_key_a_figure_reads_is_declared_or_carried_by_its_stages_artifacts(coarse_nfrc, tmp_path, figure):
    scene_path = clone(coarse_nfrc[1], tmp_path / "out")
    scene = load_scene(scene_path)
    stage = _stage_of(figure)
    fig = next(f for f in REGISTRY[stage].figures if f.name == figure)
    recorded, reads = recording_scene(scene)
    fig.draw(Context(recorded, tmp_path / "out", Progress(quiet=True)))
    assert result_keys(reads), "the drawing read no scene key: the recording sees nothing"
    assert _uncovered(reads, fig.depends + tuple(carried_to_figure(scene, stage, fig))) == []


@pytest.mark.parametrize("stage, methods", [("rom", None), ("hbm", "dlft"), ("hbm", "rl"), ("ti", None)])
def test_every_key_a_stage_computation_reads_is_declared_or_carried_upstream(coarse_nfrc, tmp_path, stage, methods):
    """Per treatment for the NFRCs: each output has its own keys (RL's penalty, not DLFT's)."""
    scene_path = clone(coarse_nfrc[1], tmp_path / "out")
    scene = load_scene(scene_path, [f"hbm.methods={methods}"] if methods else [])
    s = REGISTRY[stage]
    outputs = s.outputs(scene)
    expected = expected_inputs(scene, (stage,))
    recorded, reads = recording_scene(scene)
    ctx = Context(recorded, tmp_path / "out", Progress(quiet=True))
    for o in outputs:
        ctx.inputs[o.file], ctx.hashes[o.file] = expected[o.file]
    s.compute(ctx, outputs)
    assert result_keys(reads), "the computation read no scene key: the recording sees nothing"
    for o in outputs:
        declared = s.depends + o.depends + tuple(k for up in s.upstream for k in carried(scene, up))
        assert [k for k in _uncovered(reads, declared) if k not in LOGGED.get(stage, {})] == [], o.file


def test_renaming_the_scene_redraws_the_hbm_paraview_files(coarse_nfrc, tmp_path):
    """hbm_METHOD.pvd's comment names the scene: a new name makes the figure out of date, and
    the file drawn again names it."""
    from pipelines.stages.hbm import HBM_VTU

    scene_path = clone(coarse_nfrc[1], tmp_path / "out")
    out = tmp_path / "out"
    first, renamed = (load_scene(scene_path, [f"name={n}"]) for n in ("first", "renamed"))
    assert figure_hash(first, out, HBM_VTU) != figure_hash(renamed, out, HBM_VTU)
    update_figures(first, out, [REGISTRY["hbm"]], Progress(quiet=True))
    assert update_figures(renamed, out, [REGISTRY["hbm"]], Progress(quiet=True)) == ["hbm_vtu"]
    assert "renamed: " in (out / "figures" / "hbm_dlft.pvd").read_text()


def test_listing_the_treatments_in_another_order_redraws_the_nfrc_figure(tmp_path):
    """The NFRC curves take their colours in the order of [hbm] methods: the same files listed
    the other way round make nfrc.png out of date (the NFRCs themselves stay current)."""
    from pipelines.runner import plan
    from pipelines.stages.hbm import NFRC_FIGURE

    base = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    a, b = (load_scene(base, [f"hbm.methods={m}"]) for m in ("dlft,rl", "rl,dlft"))
    assert NFRC_FIGURE.inputs(a) == tuple(reversed(NFRC_FIGURE.inputs(b)[:2])) + ("ti.h5",)
    assert expected_inputs(a, ("hbm",)) == expected_inputs(b, ("hbm",))
    assert figure_hash(a, tmp_path, NFRC_FIGURE) != figure_hash(b, tmp_path, NFRC_FIGURE)
    assert [s.why for s in plan(b, tmp_path, ("hbm",))] == ["nfrc_rl.h5: no artifact; nfrc_dlft.h5: no artifact"]
