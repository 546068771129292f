"""The package's dependency rules, read from the source (AST, nothing imported).

* `mujoco` is imported only by the twin (twin.py) and by the compiled closed
  loop (closed_loop_kernel.py), which calls MuJoCo's library itself;
* `rerun` only by the output package (isp_twin/output/: the recorder, its
  layout and its read-back);
* `isp_twin.control` (the controller blocks) imports neither the twin nor the
  scenario nor the closed loop: it is plain math, testable alone;
* the packages follow the pipeline (`PIPELINE`): model, control, experiments,
  estimation, identification, output, diagnosis, commands; each imports only from those
  before it and the shared base, and the reference simulator from none;
* `isp_twin.model.friction` (Eq. 5, compiled by numba as written) uses only the
  math module, numpy and the vocabulary's side indices;
* the names of the gimbal axes, turntable joints and friction regimes are
  listed once, in `isp_twin.vocabulary`: a tuple, list or set literal holding
  two or more of them anywhere else in the package is a restatement (the
  independent reference simulator, `isp_twin.reference`, writes the regime
  order again on purpose and a test compares it);
* effects are looked up only through `isp_twin.model.effects.effect_class` (no
  ``EFFECTS[...]`` outside the registry), and YAML is read only by
  `isp_twin.input_files.load_yaml`.

And every function stays under 60 lines (an orchestrator reads as named
stages) except those on a commented allow-list that can only shrink.

An import counts wherever it is written (module top, inside a function, a
relative import, ``from isp_twin.model import twin``, ``importlib.import_module``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from isp_twin.vocabulary import GIMBAL_AXES, REGIMES, TABLE_JOINTS

PACKAGE = Path(__file__).resolve().parents[1] / "isp_twin"

#: Third-party module -> the files (relative to the repository) allowed to import it;
#: a name ending in "/" allows every file below that folder.
CONFINED = {
    "mujoco": {"isp_twin/model/twin.py", "isp_twin/experiments/closed_loop_kernel.py"},
    "rerun": {"isp_twin/output/"},
}
#: Package directory -> modules none of its files may import.
FORBIDDEN = {
    "isp_twin/control/": (
        "isp_twin.model.twin",
        "isp_twin.experiments.scenario",
        "isp_twin.experiments.closed_loop",
        "isp_twin.experiments.closed_loop_kernel",
        "mujoco",
    ),
}
#: The pipeline, in order: a package imports only from those before it (and
#: from the shared base: errors, units, vocabulary, resources, input_files,
#: and output.files, the atomic writing every stage uses). output (the
#: recorder and its layout) sits after the experiments whose runs it draws
#: and before the diagnosis that records its residuals.
PIPELINE = (
    "model",
    "control",
    "experiments",
    "estimation",
    "identification",
    "output",
    "diagnosis",
    "commands",
)
for _i, _package in enumerate(PIPELINE):
    FORBIDDEN.setdefault(f"isp_twin/{_package}/", ())
    FORBIDDEN[f"isp_twin/{_package}/"] += tuple(
        f"isp_twin.{later}" for later in PIPELINE[_i + 1 :] if later != "output"
    ) + (
        ("isp_twin.output.recording", "isp_twin.output.layout", "isp_twin.output.rerun_writer")
        if _i < PIPELINE.index("output")
        else ()
    )
#: The independent reference simulator shares no code with the model it judges.
FORBIDDEN["isp_twin/reference/"] = tuple(f"isp_twin.{p}" for p in PIPELINE if p != "commands") + (
    "isp_twin.vocabulary",
)

#: File -> the only modules it may import (the vocabulary: names only, so
#: that everything, Eq. 5 included, can import it).
ONLY = {
    "isp_twin/model/friction.py": ("__future__", "math", "numpy", "isp_twin.vocabulary"),
    "isp_twin/vocabulary.py": ("__future__", "isp_twin.errors"),
}


def module_name(rel: str) -> str:
    """``isp_twin/control/nfc.py`` -> ``isp_twin.control.nfc`` (a package's __init__ -> the package)."""
    parts = rel.removesuffix(".py").split("/")
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imported_modules(source: str, rel: str) -> list[tuple[int, str]]:
    """Every module a file imports, as (line, dotted name), relative imports resolved.

    ``from a.b import c`` yields both ``a.b`` and ``a.b.c`` (c may be a module).
    """
    own = module_name(rel).split(".")
    package = own if rel.endswith("__init__.py") else own[:-1]
    found = []
    for node in ast.walk(ast.parse(source, filename=rel)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            found.append((node.lineno, base))
            found += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
        elif (
            isinstance(node, ast.Call)
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
            and (
                (isinstance(node.func, ast.Name) and node.func.id == "__import__")
                or (isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
            )
        ):
            found.append((node.lineno, node.args[0].value))
    return found


def _within(name: str, module: str) -> bool:
    return name == module or name.startswith(module + ".")


def _at_home(rel: str, homes: set[str]) -> bool:
    return any(rel == home or (home.endswith("/") and rel.startswith(home)) for home in homes)


def violations(rel: str, source: str) -> list[str]:
    """The dependency rules this file breaks, one line each ("file:line: why")."""
    broken = []
    for line, name in imported_modules(source, rel):
        where = f"{rel}:{line}"
        for module, homes in CONFINED.items():
            if _within(name, module) and not _at_home(rel, homes):
                broken.append(f"{where}: imports {module} (only {', '.join(sorted(homes))})")
        for folder, banned in FORBIDDEN.items():
            if rel.startswith(folder):
                broken += [f"{where}: {folder} imports {m}" for m in banned if _within(name, m)]
        allowed = ONLY.get(rel)
        if allowed is not None and not any(_within(name, module) for module in allowed):
            top = name.split(".")[0] if name.split(".")[0] != "isp_twin" else name
            broken.append(f"{where}: imports {top} (only {', '.join(allowed)})")
    # ``from a import b`` is two names for one statement: one line per finding.
    return list(dict.fromkeys(broken))


def package_files() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_the_package_keeps_its_dependency_rules():
    root = PACKAGE.parent
    broken = []
    for path in package_files():
        broken += violations(path.relative_to(root).as_posix(), path.read_text())
    assert not broken, "\n".join(broken)


def test_the_rules_name_files_that_exist():
    root = PACKAGE.parent
    named = set().union(*CONFINED.values(), ONLY, FORBIDDEN)
    assert all((root / rel).exists() for rel in named)


@pytest.mark.parametrize(
    "rel, source",
    [
        ("isp_twin/experiments/metrics.py", "import mujoco\n"),
        ("isp_twin/experiments/metrics.py", "def f():\n    from mujoco import mjtObj\n"),
        (
            "isp_twin/experiments/metrics.py",
            "import importlib\nimportlib.import_module('mujoco')\n",
        ),
        ("isp_twin/diagnosis/report.py", "import rerun.blueprint as rrb\n"),
        ("isp_twin/model/twin.py", "__import__('rerun')\n"),
        ("isp_twin/commands/run.py", "import rerun as rr\n"),
        ("isp_twin/experiments/results.py", "from rerun.chunk import RrdReader\n"),
        ("isp_twin/outputs/layout.py", "import rerun.blueprint as rrb\n"),  # not the package
        ("isp_twin/control/pi.py", "from isp_twin.model.twin import Twin\n"),
        ("isp_twin/control/pi.py", "from isp_twin.experiments import scenario\n"),
        ("isp_twin/control/pi.py", "from ..experiments import closed_loop\n"),
        ("isp_twin/control/pi.py", "from ..experiments.closed_loop_kernel import advance\n"),
        ("isp_twin/control/__init__.py", "from ..model.twin import Twin\n"),
        ("isp_twin/model/axis_model.py", "from isp_twin.identification.fit import identify\n"),
        ("isp_twin/model/parameters.py", "from ..experiments import scenario\n"),
        ("isp_twin/experiments/metrics.py", "from isp_twin.diagnosis import search\n"),
        ("isp_twin/identification/fit.py", "from isp_twin.output.layout import run_blueprint\n"),
        ("isp_twin/output/layout.py", "from ..commands import run\n"),
        ("isp_twin/reference/axis.py", "from isp_twin.model.friction import stribeck\n"),
        ("isp_twin/model/friction.py", "import scipy.special\n"),
        ("isp_twin/model/friction.py", "from isp_twin.model.twin import Twin\n"),
    ],
)
def test_a_planted_violation_is_caught(rel, source):
    assert violations(rel, source)


@pytest.mark.parametrize(
    "rel, source",
    [
        ("isp_twin/model/twin.py", "import mujoco\n"),
        ("isp_twin/output/recording.py", "import rerun as rr\n"),
        ("isp_twin/output/readback.py", "from rerun.chunk import RrdReader\n"),
        ("isp_twin/output/layout.py", "import rerun.blueprint as rrb\n"),
        ("isp_twin/control/pi.py", "from isp_twin.units import DEG\nfrom . import bound\n"),
        ("isp_twin/control/rate_loop.py", "from isp_twin.control.nfc import FrictionFeedForward\n"),
        (
            "isp_twin/experiments/closed_loop.py",
            "from isp_twin.experiments.scenario import Scenario\n",
        ),
        ("isp_twin/model/friction.py", "from __future__ import annotations\nimport math\n"),
        (
            "isp_twin/experiments/metrics.py",
            "import mujoco_menagerie_helpers\n",
        ),  # a prefix is not a match
    ],
)
def test_allowed_imports_pass(rel, source):
    assert violations(rel, source) == []


#: The names only `isp_twin.vocabulary` may list.
VOCABULARY = frozenset(GIMBAL_AXES + TABLE_JOINTS + REGIMES)
#: Where a list of them is allowed: their home, and the deliberately independent simulator.
VOCABULARY_HOMES = ("isp_twin/vocabulary.py", "isp_twin/reference/")


def restated_names(rel: str, source: str) -> list[str]:
    """Tuple/list/set literals holding two or more vocabulary names, nested
    literals included ("file:line: names"; the outermost literal only)."""
    if rel.startswith(VOCABULARY_HOMES):
        return []
    found = {}
    for node in ast.walk(ast.parse(source, filename=rel)):
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            names = [
                e.value
                for e in ast.walk(node)
                if isinstance(e, ast.Constant)
                and isinstance(e.value, str)
                and e.value in VOCABULARY
            ]
            if len(names) >= 2:
                # ast.walk is breadth first: the outermost literal of a line comes first.
                found.setdefault(
                    node.lineno,
                    f"{rel}:{node.lineno}: lists {', '.join(names)} (import them from isp_twin.vocabulary)",
                )
    return list(found.values())


def test_axis_joint_and_regime_names_are_listed_only_in_the_vocabulary():
    root = PACKAGE.parent
    found = []
    for path in package_files():
        found += restated_names(path.relative_to(root).as_posix(), path.read_text())
    assert not found, "\n".join(found)


@pytest.mark.parametrize(
    "source",
    [
        'AXES: tuple[str, ...] = ("inner_az", "inner_el", "outer_az", "outer_el")\n',
        'JOINTS = (("table_yaw", "z"), ("table_pitch", "y"))\n',
        'def f(axes=["inner_az", "inner_el"]):\n    pass\n',
        'ok = axis in {"R+", "L-"}\n',
    ],
)
def test_a_planted_list_of_names_is_caught(source):
    assert restated_names("isp_twin/experiments/metrics.py", source)


@pytest.mark.parametrize(
    "rel, source",
    [
        (
            "isp_twin/experiments/metrics.py",
            'def f(axis="inner_az"):\n    return axis == "inner_el"\n',
        ),
        (
            "isp_twin/experiments/metrics.py",
            'PAIRS = (("inner_az", 1.0),)\n',
        ),  # one name per literal
        ("isp_twin/vocabulary.py", 'INNER_AXES = ("inner_az", "inner_el")\n'),
        ("isp_twin/reference/axis.py", 'REGIME_NAMES = ("R+", "R-", "L+", "L-")\n'),
    ],
)
def test_single_names_and_the_vocabulary_itself_pass(rel, source):
    assert restated_names(rel, source) == []


def registry_lookups(rel: str, source: str) -> list[str]:
    """``EFFECTS[...]`` outside the registry's module ("file:line")."""
    if rel == "isp_twin/model/effects/__init__.py":
        return []
    return [
        f"{rel}:{node.lineno}: EFFECTS[...] (use isp_twin.model.effects.effect_class)"
        for node in ast.walk(ast.parse(source, filename=rel))
        if isinstance(node, ast.Subscript)
        and isinstance(node.value, (ast.Name, ast.Attribute))
        and getattr(node.value, "id", getattr(node.value, "attr", None)) == "EFFECTS"
    ]


def test_effects_are_looked_up_by_one_function():
    root = PACKAGE.parent
    found = []
    for path in package_files():
        found += registry_lookups(path.relative_to(root).as_posix(), path.read_text())
    assert not found, "\n".join(found)
    assert registry_lookups("isp_twin/diagnosis/search.py", "cls = effects.EFFECTS[name]\n")
    assert registry_lookups("isp_twin/model/twin.py", "cls = EFFECTS[spec.name]\n")


#: PyYAML's readers: only `isp_twin.input_files.load_yaml` calls them (one
#: loader: numbers like 1e-3, file name and line in the one-line error).
YAML_READERS = frozenset(
    {"load", "safe_load", "full_load", "unsafe_load", "load_all", "safe_load_all"}
)


def yaml_reads(rel: str, source: str) -> list[str]:
    """Calls of ``yaml.<reader>(...)`` outside input_files.py ("file:line")."""
    if rel == "isp_twin/input_files.py":
        return []
    return [
        f"{rel}:{node.lineno}: yaml.{node.func.attr} (use isp_twin.input_files.load_yaml)"
        for node in ast.walk(ast.parse(source, filename=rel))
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and node.func.attr in YAML_READERS
        and isinstance(node.func.value, ast.Name)
        and node.func.value.id == "yaml"
    ]


def test_yaml_is_read_by_one_loader():
    root = PACKAGE.parent
    found = []
    for path in package_files():
        found += yaml_reads(path.relative_to(root).as_posix(), path.read_text())
    assert not found, "\n".join(found)
    assert yaml_reads(
        "isp_twin/experiments/sweep/design.py", "raw = yaml.safe_load(path.read_text())\n"
    )
    assert yaml_reads("isp_twin/experiments/rig.py", "import yaml\nraw = yaml.load(t, Loader=L)\n")
    assert yaml_reads("isp_twin/model/parameters.py", "text = yaml.safe_dump(raw)\n") == []


# --------------------------------------------------------------------------
# Function length: an orchestrator reads as named stages, each under ~60 lines.

MAX_FUNCTION_LINES = 60
#: Functions allowed to be longer ("file::qualified name"), each with why. The
#: list only shrinks: an entry that is gone or has come under the limit fails
#: `test_the_long_function_allow_list_only_shrinks`, so it is struck when split.
LONG_FUNCTIONS = {
    # Compiled kernels, kept whole: numba compiles each as one function, its
    # state in locals (a split would pass it through arrays), and each is
    # checked bit for bit against a plain Python form.
    "isp_twin/experiments/closed_loop_kernel.py::_advance",
    "isp_twin/model/substep_model.py::_advance_group",
    # The fast model's batched loop over samples (Eq. 6): the hot path of
    # identification, one friction-law evaluation per sample (issue 11, item 1).
    "isp_twin/model/axis_model.py::simulate",
    # The reference simulator's integrator, compiled: one loop over samples,
    # sub-steps and events sharing its local state (docs/reference_simulator.md).
    "isp_twin/reference/axis.py::_integrate",
    # Report writers and the residual analysis: a report is a list of
    # sections (issue 8 item 5 moved the intervals, BIC and parameter file
    # into isp_twin/estimation/ and split lm_steps into sub-generators).
    "isp_twin/identification/report.py::write_report",
    "isp_twin/identification/report.py::result_json",
    "isp_twin/diagnosis/report.py::write_report",
    "isp_twin/diagnosis/residual.py::analyse",
}


def function_lengths(source: str, rel: str) -> dict[str, int]:
    """Every function's length in lines (decorators included), by ``file::qualified name``.

    Functions nested in functions, classes or module-level blocks (``if``,
    ``try``) count on their own and as part of their parent.
    """
    lengths = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                start = min([child.lineno] + [d.lineno for d in child.decorator_list])
                lengths[f"{rel}::{prefix}{child.name}"] = child.end_lineno - start + 1
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(source, filename=rel), "")
    return lengths


def package_function_lengths() -> dict[str, int]:
    root = PACKAGE.parent
    lengths = {}
    for path in package_files():
        lengths.update(function_lengths(path.read_text(), path.relative_to(root).as_posix()))
    return lengths


def test_functions_stay_under_60_lines_outside_the_allow_list():
    long = {
        name: n
        for name, n in package_function_lengths().items()
        if n > MAX_FUNCTION_LINES and name not in LONG_FUNCTIONS
    }
    assert not long, "split into named stages:\n" + "\n".join(
        f"{name}: {n} lines" for name, n in sorted(long.items())
    )


def test_the_long_function_allow_list_only_shrinks():
    lengths = package_function_lengths()
    stale = sorted(n for n in LONG_FUNCTIONS if lengths.get(n, 0) <= MAX_FUNCTION_LINES)
    assert not stale, "gone or now short; strike from LONG_FUNCTIONS:\n" + "\n".join(stale)


def test_function_lengths_count_nested_and_decorated_functions():
    source = (
        "if True:\n"
        "    @decorate\n"
        "    def kernel(x):\n"
        "        def inner():\n"
        "            pass\n"
        "        return x\n"
        "class A:\n"
        "    def method(self):\n"
        "        pass\n"
    )
    assert function_lengths(source, "m.py") == {
        "m.py::kernel": 5,
        "m.py::kernel.inner": 2,
        "m.py::A.method": 2,
    }
