"""Arguments of the public API: a value of the wrong type is a `TypeError` or `ValueError` whose
message names the argument (PyO3 names it only in a note of the exception, and `os.fspath`,
`float` or a `for` loop not at all), and every signature shows its real defaults (PyO3 shows a
default that is no Python literal in Rust, such as `"sage".to_string()`, as `...`).

The public API is what `sage3d.__all__` names (functions, and the constructors and public
methods of its classes) and the public functions of `sage3d.distributed`; a test fails when one
of their parameters has no wrong-type case below."""

import functools
import inspect
import json
import re

import pytest

import sage3d
import sage3d.distributed as distributed
from conftest import SMALL_ENV, SMALL_SYNTH

pytestmark = pytest.mark.usefixtures("synth_cache")

#: A path that is no scene, dataset or run: where a call would go on past its arguments, it
#: fails at once instead of doing work.
NOWHERE = "/nonexistent-sage3d-arguments"


class Fixtures:
    """What the cases call methods of, made on first use: a small synthetic scene, environments
    over it, a dataset folder and a training set with nothing in them."""

    def __init__(self, tmp_path_factory):
        self.tmp = tmp_path_factory.mktemp("arguments")

    @functools.cached_property
    def scene(self):
        return sage3d.synth_scene(**SMALL_SYNTH)

    @functools.cached_property
    def env(self):
        return sage3d.make_env(**SMALL_ENV)

    @functools.cached_property
    def vec(self):
        return sage3d.make_vec_env(2, **SMALL_ENV)

    @functools.cached_property
    def dataset(self):
        root = self.tmp / "dataset"
        (root / "episodes").mkdir(parents=True)
        (root / "episodes" / "train.jsonl").write_text("")
        (root / "splits.json").write_text(json.dumps({"splits": {"train": []}}))
        return root

    @functools.cached_property
    def training_set(self):
        root = self.tmp / "training"
        root.mkdir()
        (root / "manifest.json").write_text(json.dumps(
            {"settings": {"format": "frames"}, "counts": {"kept": 0}, "files": []}))
        return sage3d.TrainingSet(root)


@pytest.fixture(scope="module")
def fx(tmp_path_factory):
    return Fixtures(tmp_path_factory)


def pathfinder(fx):
    return fx.scene.pathfinder


def evaluate(fx, *args, **kw):
    """`sage3d.evaluate` of the oracle over the empty dataset, `kw` overriding."""
    return sage3d.evaluate(*args or (fx.dataset,), **{"agent": "oracle", "out": NOWHERE, **kw})


def env_cases(qualname, make):
    """A case per keyword argument of the environments (`SageEnv`, `SageVectorEnv`)."""
    bad = {"render_mode": 5, "scene": 5, "dataset": 5, "scenes": 5, "split": 5, "episodes": 5,
           "task": 5, "filters": 5, "num_episodes": "8", "seed": "0", "synth": 5, "preset": 5,
           "width": "32", "height": 2.5, "sensors": 5, "actions": 5, "look": "yes",
           "max_steps": "9", "hfov": "90", "config": 5, "mode": 5, "device": 5}
    # `scenes` is checked with a dataset, as it is read only then.
    extra = {"scenes": {"dataset": NOWHERE}}
    return [(qualname, k, lambda fx, k=k, v=v: make(**{**SMALL_ENV, **extra.get(k, {}), k: v}))
            for k, v in bad.items()]


#: (public callable, parameter, a call that gives that parameter a wrong value).
CASES = [
    ("Dataset", "path", lambda fx: sage3d.Dataset(5)),
    ("Dataset.episodes", "split", lambda fx: sage3d.Dataset(fx.dataset).episodes(5)),
    ("load_dataset", "path", lambda fx: sage3d.load_dataset(5)),
    ("filter_episodes", "episodes", lambda fx: sage3d.filter_episodes(5)),
    ("PathFinder.find_path", "start", lambda fx: pathfinder(fx).find_path("ab", [0, 0])),
    ("PathFinder.find_path", "goal", lambda fx: pathfinder(fx).find_path([0, 0], 3)),
    ("PathFinder.geodesic_distance", "a", lambda fx: pathfinder(fx).geodesic_distance(None, [0, 0])),
    ("PathFinder.geodesic_distance", "b", lambda fx: pathfinder(fx).geodesic_distance([0, 0], "b")),
    ("PathFinder.is_navigable", "p", lambda fx: pathfinder(fx).is_navigable({"x": 1})),
    ("PathFinder.snap_point", "p", lambda fx: pathfinder(fx).snap_point("p")),
    ("PathFinder.snap_point", "max_distance", lambda fx: pathfinder(fx).snap_point([0, 0], "1")),
    ("PathFinder.seed", "seed", lambda fx: pathfinder(fx).seed(1.5)),
    ("PathFinder.sample_navigable_point", "island", lambda fx: pathfinder(fx).sample_navigable_point("0")),
    ("PathFinder.island", "p", lambda fx: pathfinder(fx).island(7)),
    *env_cases("SageEnv", sage3d.SageEnv),
    ("SageEnv.reset", "seed", lambda fx: fx.env.reset(seed="1")),
    ("SageEnv.reset", "options", lambda fx: fx.env.reset(options=5)),
    ("SageEnv.step", "action", lambda fx: fx.env.step("forward")),
    ("SageVectorEnv", "num_envs", lambda fx: sage3d.SageVectorEnv("2", **SMALL_ENV)),
    *env_cases("SageVectorEnv", lambda **kw: sage3d.SageVectorEnv(2, **kw)),
    ("SageVectorEnv.reset", "seed", lambda fx: fx.vec.reset(seed="12")),
    ("SageVectorEnv.reset", "options", lambda fx: fx.vec.reset(options=[0, 1])),
    ("SageVectorEnv.step", "actions", lambda fx: fx.vec.step(5)),
    ("Scene.load", "path", lambda fx: sage3d.Scene.load(5)),
    ("Scene.load", "cache", lambda fx: sage3d.Scene.load(NOWHERE, cache=5)),
    ("Scene.load", "collision", lambda fx: sage3d.Scene.load(NOWHERE, collision=5)),
    ("Scene.load", "splat_bodies", lambda fx: sage3d.Scene.load(NOWHERE, splat_bodies=5)),
    ("Scene.synth", "cache", lambda fx: sage3d.Scene.synth(5)),
    ("Scene.synth", "seed", lambda fx: sage3d.Scene.synth(fx.tmp, seed="1")),
    ("Scene.synth", "kind", lambda fx: sage3d.Scene.synth(fx.tmp, kind=1)),
    ("Scene.synth", "rooms", lambda fx: sage3d.Scene.synth(fx.tmp, rooms=-1)),
    ("Scene.synth", "objects", lambda fx: sage3d.Scene.synth(fx.tmp, objects=2.5)),
    ("Scene.synth", "gaussians", lambda fx: sage3d.Scene.synth(fx.tmp, gaussians="many")),
    ("Scene.episodes", "count", lambda fx: fx.scene.episodes(count="8")),
    ("Scene.episodes", "seed", lambda fx: fx.scene.episodes(seed=-1)),
    ("TrainingSet", "path", lambda fx: sage3d.TrainingSet(5)),
    ("TrainingSet.episodes", "images", lambda fx: fx.training_set.episodes(images="no")),
    ("TrainingSet.episodes", "shard", lambda fx: fx.training_set.episodes(shard=2)),
    ("TrainingSet.samples", "shard", lambda fx: fx.training_set.samples(shard=(2, 1))),
    ("build_dataset", "scenes", lambda fx: sage3d.build_dataset(5, fx.tmp / "data")),
    ("build_dataset", "out", lambda fx: sage3d.build_dataset(NOWHERE, 5)),
    ("build_dataset", "force",
     lambda fx: sage3d.build_dataset(NOWHERE, fx.tmp / "data", force="yes")),
    ("demo", "out", lambda fx: sage3d.demo(5)),
    ("env_config", "preset", lambda fx: sage3d.env_config(5)),
    ("env_config", "overrides", lambda fx: sage3d.env_config("sage", {"task": {"max_steps": 9}})),
    ("evaluate", "dataset", lambda fx: evaluate(fx, 5)),
    ("evaluate", "scenes", lambda fx: evaluate(fx, fx.dataset, 5)),
    ("evaluate", "agent", lambda fx: evaluate(fx, agent=5)),
    ("evaluate", "out", lambda fx: evaluate(fx, out=5)),
    ("evaluate", "width", lambda fx: evaluate(fx, width="64")),
    ("evaluate", "height", lambda fx: evaluate(fx, height=0.5)),
    ("evaluate", "sensors", lambda fx: evaluate(fx, sensors=5)),
    ("evaluate", "config", lambda fx: evaluate(fx, config="{}")),
    ("evaluate", "scenes_only", lambda fx: evaluate(fx, scenes_only=5)),
    ("evaluate", "strict", lambda fx: evaluate(fx, strict="yes")),
    ("evaluate", "force", lambda fx: evaluate(fx, force="yes")),
    ("make_env", "task", lambda fx: sage3d.make_env(task=5, **SMALL_ENV)),
    ("make_env", "render_mode", lambda fx: sage3d.make_env(render_mode="human", **SMALL_ENV)),
    ("make_vec_env", "num_envs", lambda fx: sage3d.make_vec_env(2.0, **SMALL_ENV)),
    ("make_vec_env", "task", lambda fx: sage3d.make_vec_env(2, task=["vln", 5], **SMALL_ENV)),
    ("make_vec_env", "render_mode",
     lambda fx: sage3d.make_vec_env(2, render_mode=1, **SMALL_ENV)),
    ("render_training_data", "dataset", lambda fx: sage3d.render_training_data(5, None, fx.tmp / "t")),
    ("render_training_data", "scenes",
     lambda fx: sage3d.render_training_data(fx.dataset, 5, fx.tmp / "t")),
    ("render_training_data", "out", lambda fx: sage3d.render_training_data(fx.dataset, None, 5)),
    ("render_training_data", "force",
     lambda fx: sage3d.render_training_data(fx.dataset, None, fx.tmp / "t", force=1)),
    ("synth_scene", "seed", lambda fx: sage3d.synth_scene(seed="2")),
    ("synth_scene", "kind", lambda fx: sage3d.synth_scene(kind=2)),
    ("synth_scene", "rooms", lambda fx: sage3d.synth_scene(rooms=3.0)),
    ("synth_scene", "objects", lambda fx: sage3d.synth_scene(objects=None)),
    ("synth_scene", "gaussians", lambda fx: sage3d.synth_scene(gaussians="20000")),
    ("synth_scene", "cache", lambda fx: sage3d.synth_scene(cache=5)),
    *[("view", k, lambda fx, k=k, v=v: sage3d.view(NOWHERE, **{k: v}))
      for k, v in {"scenes": 5, "split": 5, "play": 5, "force": "yes", "preset": 5, "mode": 5,
                   "device": 5, "host": 5, "port": "8765", "public": "yes",
                   "on_ready": "print"}.items()],
    ("view", "path", lambda fx: sage3d.view(5)),
    ("distributed.generate", "scenes", lambda fx: distributed.generate(5, fx.tmp / "d")),
    ("distributed.generate", "out", lambda fx: distributed.generate(NOWHERE, 5)),
    ("distributed.generate", "num_cpus",
     lambda fx: distributed.generate(NOWHERE, fx.tmp / "d", num_cpus="1")),
    ("distributed.generate", "progress",
     lambda fx: distributed.generate(NOWHERE, fx.tmp / "d", progress="no")),
    *[("distributed.evaluate", k, lambda fx, k=k, v=v: distributed.evaluate(
        **{"dataset": fx.dataset, "agent": "oracle", "out": fx.tmp / "r", k: v}))
      for k, v in {"dataset": 5, "scenes": 5, "agent": 5, "out": 5, "width": "64",
                   "height": "64", "sensors": 5, "config": 5, "num_cpus": "1",
                   "max_retries": -1, "progress": "no"}.items()],
    *[("distributed.render_training_data", k,
       lambda fx, k=k, v=v: distributed.render_training_data(
           **{"dataset": fx.dataset, "scenes": None, "out": fx.tmp / "t", k: v}))
      for k, v in {"dataset": 5, "scenes": 5, "out": 5, "num_cpus": "1", "force": 1,
                   "progress": "no"}.items()],
]

#: Keyword arguments gathered by `**` (filters, settings, options), named as the others are.
KEYWORD_CASES = [
    ("Dataset.episodes", "level", lambda fx: sage3d.Dataset(fx.dataset).episodes(level=1)),
    ("filter_episodes", "scene", lambda fx: sage3d.filter_episodes([], scene={"a": 1})),
    ("build_dataset", "per_scene",
     lambda fx: sage3d.build_dataset(NOWHERE, fx.tmp / "data", per_scene="x")),
    ("demo", "seed", lambda fx: sage3d.demo(fx.tmp / "demo", seed={1, 2})),
    ("evaluate", "split", lambda fx: evaluate(fx, split=3)),
    ("render_training_data", "width",
     lambda fx: sage3d.render_training_data(fx.dataset, None, NOWHERE, width="x")),
    ("render_training_data", "answers",
     lambda fx: sage3d.render_training_data(fx.dataset, None, NOWHERE, answers=5)),
]


def names(message, parameter):
    """Whether `message` names `parameter` as an argument: `parameter:` (`find_path: start:
    expected ...`) or, for a keyword of a settings struct, `` `parameter` ``."""
    p = re.escape(parameter)
    return re.search(rf"(^|[\s.]){p}:|`{p}`", message) is not None


@pytest.mark.parametrize("qualname, parameter, call", [pytest.param(*c, id=f"{c[0]}-{c[1]}")
                                                      for c in CASES + KEYWORD_CASES])
def test_a_wrong_argument_is_named(fx, qualname, parameter, call):
    with pytest.raises((TypeError, ValueError)) as e:
        call(fx)
    message = str(e.value)
    assert names(message, parameter), f"{qualname}: the error does not name {parameter!r}: {message}"


def public_callables():
    """`(qualified name, callable, whether its first parameter is self)` of the public API."""
    out = []
    for name in sage3d.__all__:
        obj = getattr(sage3d, name)
        if inspect.isclass(obj):
            for cls in obj.__mro__:
                if not cls.__module__.startswith("sage3d"):
                    continue
                for attr, member in vars(cls).items():
                    if attr == "__init__":
                        out.append((name, member, True))
                    elif attr.startswith("_"):
                        continue
                    elif isinstance(member, staticmethod):
                        out.append((f"{name}.{attr}", member.__func__, False))
                    elif callable(member):
                        out.append((f"{name}.{attr}", member, True))
        elif callable(obj):
            out.append((name, obj, False))
    for name, func in vars(distributed).items():
        if inspect.isfunction(func) and func.__module__ == distributed.__name__ \
                and not name.startswith("_"):
            out.append((f"distributed.{name}", func, False))
    return out


def parameters(func, bound):
    """The named parameters of `func` (not `*args`, `**kwargs`, nor `self` when `bound`)."""
    params = list(inspect.signature(func).parameters.values())
    return [p for p in params[1 if bound else 0:] if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def test_every_public_parameter_has_a_case():
    public = {(q, p.name) for q, f, bound in public_callables() for p in parameters(f, bound)}
    covered = {(q, p) for q, p, _ in CASES}
    assert public - covered == set(), "parameters without a wrong-type case"
    assert covered - public == set(), "cases of parameters the public API does not have"


def test_signatures_show_their_defaults():
    # The public API and every function and method of the compiled module: no default shown as
    # `...` (Ellipsis), which `help()` and `inspect.signature` would print.
    native = sage3d._sage3d
    funcs = public_callables()
    for name in native.__all__:
        obj = getattr(native, name)
        if inspect.isclass(obj):
            funcs += [(f"{name}.{attr}", m.__func__ if isinstance(m, staticmethod) else m,
                       not isinstance(m, staticmethod))
                      for attr, m in vars(obj).items() if not attr.startswith("_") and
                      (callable(m) or isinstance(m, staticmethod))]
        elif callable(obj):
            funcs.append((name, obj, False))
    shown = {f"{q}({p.name})": p.default for q, f, bound in funcs for p in parameters(f, bound)}
    assert [k for k, v in shown.items() if v is Ellipsis] == []
    assert {k: v for k, v in shown.items() if k.startswith("view(")} == {
        "view(path)": inspect.Parameter.empty, "view(scenes)": None, "view(split)": None,
        "view(play)": None, "view(force)": False, "view(preset)": "sage", "view(mode)": "sage",
        "view(device)": "cpu", "view(host)": "127.0.0.1", "view(port)": 8765,
        "view(public)": False, "view(on_ready)": None}
    assert str(inspect.signature(sage3d.env_config)) == "(preset='sage', overrides='{}')"
    assert str(inspect.signature(sage3d.Scene.synth)) == \
        "(cache, seed=0, kind='home', rooms=4, objects=40, gaussians=60000)"
