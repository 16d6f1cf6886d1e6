"""Bad input wherever a user types: properties over arbitrary values (hypothesis).

Every public entry point a user feeds by hand -- ``Guide.instruct`` / ``instruct_batch``, the gymnasium envs'
``reset(seed=..., options=...)`` and ``step``, the command line of ``python -m agrl.train`` / ``agrl.evaluate`` --
either answers (the right type and shape, finite numbers) or raises the project's error type with one line that
names the value and what is allowed; never another exception, and a refused command writes nothing. The command
line's checks run in-process (:func:`agrl.cli.run_checked`, with the entry point's own input checks and, in place of
Hydra, a function that records that the run would start). What a real process adds to a refusal (interpreter start-up,
the module's ``__main__``, the exit status, the stderr of a fresh interpreter) is the same for every refusal made at
the same stage: tests/test_train_cli.py and tests/test_evaluate_cli.py run one refused command line of each stage of
each entry point as a real process.

The examples are the same on every run (``tests/conftest.py`` loads a derandomized hypothesis profile).
"""

from __future__ import annotations

import contextlib
import io
import math
import shutil
import sys
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from omegaconf import OmegaConf

from agrl.cli import run_checked
from agrl.config import compose_config, one_line, override_key
from agrl.envs.gym import ENV_ID
from agrl.guide import Guide, GuideError

# ---------------------------------------------------------------------------- values
#: Scalars of every kind: None, truth values, integers far beyond int64, floats with NaN, infinities and
#: subnormals, complex numbers, short texts and bytes.
SCALARS = st.one_of(st.none(), st.booleans(), st.integers(), st.integers(-2**70, 2**70), st.floats(),
                    st.complex_numbers(), st.text(max_size=4), st.binary(max_size=3))
#: numpy arrays of any common dtype, 0 to 3 dimensions.
ARRAYS = hnp.arrays(dtype=st.sampled_from([np.float32, np.float64, np.int64, np.uint8, np.bool_, np.complex64,
                                           np.dtype("<U3")]),
                    shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=8))


ANY_FLOAT = st.floats()


def numbers(width: int, elements: st.SearchStrategy = ANY_FLOAT) -> st.SearchStrategy:
    """``width`` numbers (of ``elements``: by default any float, NaN, infinities and 1e308 included)."""
    return st.lists(elements, min_size=width, max_size=width)


def anything(width: int) -> st.SearchStrategy:
    """What a user might pass where ``width`` numbers belong: the right count of any floats, lists of the wrong
    length or of other things, ragged nests, arrays of wrong dtype or shape, scalars, dicts."""
    return st.one_of(
        numbers(width), numbers(width, st.floats(-1e4, 1e4)), st.lists(SCALARS, max_size=width + 2),
        st.lists(st.lists(st.floats(-1e4, 1e4), max_size=width + 1), max_size=3), ARRAYS, SCALARS,
        st.dictionaries(st.text(max_size=3), SCALARS, max_size=3),
        numbers(width, st.floats(-1e4, 1e4)).map(np.array),
    )


def assert_one_line_naming(error: BaseException, names: tuple[str, ...]) -> str:
    """The message is one line that starts by naming one of ``names`` and says what is allowed; returns it."""
    message = str(error)
    assert message and "\n" not in message and "\r" not in message, repr(message)
    assert message.startswith(tuple(f"{name}{mark}" for name in names for mark in ("=", " of ", "["))), message
    assert " allowed" in message, message
    return message


# ---------------------------------------------------------------------------- Guide
@pytest.fixture(scope="module")
def guide() -> Guide:
    return Guide.load("baseline")


LAST_ACTIONS = st.one_of(st.integers(-2, 8), st.sampled_from([np.int64(3), np.uint8(6)]), SCALARS)
#: States a guide may meet in flight (the airspace and speeds of conf/simulation/paper.yaml, with a margin).
AIRCRAFT = st.tuples(st.floats(-2e4, 2e4), st.floats(-2e4, 2e4), st.floats(-1e3, 6e3), st.floats(50, 300),
                     st.floats(-1, 1), st.floats(-10, 10), st.floats(-1.5, 1.5)).map(list)
DESTINATIONS = st.tuples(st.floats(-2e4, 2e4), st.floats(-2e4, 2e4), st.floats(-1e3, 6e3),
                         st.floats(-10, 10)).map(list)


@settings(max_examples=150)
@given(aircraft=st.one_of(AIRCRAFT, anything(7)), destination=st.one_of(DESTINATIONS, anything(4)),
       last_action=LAST_ACTIONS)
def test_instruct_answers_a_maneuver_or_names_the_bad_value(guide, aircraft, destination, last_action):
    try:
        maneuver = guide.instruct(aircraft, destination, last_action)
    except GuideError as error:
        message = assert_one_line_naming(error, ("aircraft_state", "last_action"))
        named = {"aircraft_state": aircraft, "last_action": last_action}[message.split("=", 1)[0]]
        assert message.split("=", 1)[1].startswith(one_line(named)[:40]), message  # the value, as command
        return
    assert type(maneuver) is int and 0 <= maneuver < 7


@settings(max_examples=150)
@given(aircraft=st.one_of(st.lists(AIRCRAFT, min_size=1, max_size=4), anything(7)),
       destination=st.one_of(st.lists(DESTINATIONS, min_size=1, max_size=4), anything(4)),
       last_action=st.one_of(st.lists(st.integers(-1, 7), max_size=4), ARRAYS, SCALARS))
def test_instruct_batch_answers_maneuvers_or_names_the_bad_value(guide, aircraft, destination, last_action):
    try:
        maneuvers = guide.instruct_batch(aircraft, destination, last_action)
    except GuideError as error:
        assert_one_line_naming(error, ("aircraft_state", "destination_state", "last_action"))
        return
    assert isinstance(maneuvers, np.ndarray) and maneuvers.dtype == np.int64
    assert maneuvers.shape == (len(aircraft),) and ((maneuvers >= 0) & (maneuvers < 7)).all()


@settings(max_examples=100)
@given(aircraft=st.one_of(AIRCRAFT, anything(7)), destination=st.one_of(DESTINATIONS, anything(4)))
def test_one_question_and_a_batch_of_one_take_the_same_states(guide, aircraft, destination):
    """``instruct`` refuses exactly what ``instruct_batch`` refuses as one row (strings, truth values, numbers
    beyond float32, wrong lengths), so that a state is not good or bad by the form of the question."""
    outcomes = []
    for ask in (lambda: guide.instruct(aircraft, destination, 0),
                lambda: guide.instruct_batch([aircraft], [destination], [0])):
        try:
            ask()
            outcomes.append("answered")
        except GuideError:
            outcomes.append("refused")
    assert outcomes[0] == outcomes[1], outcomes


# ---------------------------------------------------------------------------- gymnasium envs
#: Scenario values the simulator takes (conf/simulation/paper.yaml's airspace and limits) and values around them.
SCENARIO_AIRCRAFT = st.tuples(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4), st.floats(0, 5e3), st.floats(100, 250),
                              st.floats(-0.5, 0.5), st.floats(-10, 10), st.floats(-1.5, 1.5)).map(list)
SCENARIO_DESTINATIONS = st.tuples(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4), st.floats(0, 5e3),
                                  st.floats(-10, 10)).map(list)
SCENARIO_VALUES = {
    "aircraft_state": st.one_of(SCENARIO_AIRCRAFT, SCENARIO_AIRCRAFT.map(lambda row: [row] * 4), anything(7)),
    "destination_state": st.one_of(SCENARIO_DESTINATIONS, anything(4)),
    "destination_speed": st.one_of(st.floats(0, 250), st.floats(), SCALARS, ARRAYS),
    "destination_turn_rate": st.one_of(st.floats(-0.1, 0.1), st.floats(), SCALARS, ARRAYS),
}
OPTIONS = st.one_of(
    st.none(), SCALARS, ARRAYS, st.lists(SCALARS, max_size=3),
    st.fixed_dictionaries({"aircraft_state": SCENARIO_VALUES["aircraft_state"]},
                          optional={key: value for key, value in SCENARIO_VALUES.items() if key != "aircraft_state"}),
    st.dictionaries(st.one_of(st.sampled_from(list(SCENARIO_VALUES)), st.text(max_size=4), st.integers()),
                    st.one_of(SCALARS, SCENARIO_AIRCRAFT), max_size=3),
)
SEEDS = st.one_of(st.none(), st.integers(0, 2**64 - 1), st.integers(-2**70, 2**70), SCALARS,
                  st.sampled_from([np.int64(7), np.uint64(2**64 - 1)]), st.lists(st.integers(0, 9), max_size=2))
ACTIONS = st.one_of(st.integers(-2, 8), st.floats(), SCALARS, ARRAYS, st.lists(st.integers(0, 6), max_size=2),
                    st.sampled_from([np.int64(3), np.float32(2.0), np.array(4), np.array(2.5)]))


def assert_observation(env_space, observation) -> None:
    assert isinstance(observation, np.ndarray) and observation.dtype == np.float32
    assert observation.shape == env_space.shape and np.isfinite(observation).all()
    assert env_space.contains(observation), observation


@pytest.fixture(scope="module")
def single_env():
    env = gymnasium.make(ENV_ID, task="curved")
    yield env
    env.close()


@settings(max_examples=120)
@given(seed=SEEDS, options=OPTIONS, action=ACTIONS)
def test_the_single_env_resets_and_steps_or_names_the_bad_value(single_env, seed, options, action):
    try:
        observation, info = single_env.reset(seed=seed, options=options)
    except ValueError as error:
        assert_one_line_naming(error, ("seed", "options", *SCENARIO_VALUES))
        observation, info = single_env.reset(seed=0)
    assert_observation(single_env.observation_space, observation)
    assert info["outcome"] == "running" and np.isfinite(info["aircraft_state"]).all()
    try:
        observation, reward, terminated, truncated, info = single_env.step(action)
    except ValueError as error:
        assert_one_line_naming(error, ("action",))
        observation, reward, terminated, truncated, info = single_env.step(0)  # the env goes on after a refusal
    assert_observation(single_env.observation_space, observation)
    assert isinstance(reward, float) and math.isfinite(reward)
    assert isinstance(terminated, bool) and truncated is False
    assert np.isfinite(info["aircraft_state"]).all() and np.isfinite(info["destination_state"]).all()


@pytest.fixture(scope="module")
def vector_env():
    envs = gymnasium.make_vec(ENV_ID, num_envs=4, vectorization_mode="vector_entry_point", task="irregular")
    yield envs
    envs.close()


VECTOR_ACTIONS = st.one_of(hnp.arrays(np.int64, 4, elements=st.integers(0, 6)), ACTIONS,
                           st.lists(st.one_of(st.integers(-1, 7), SCALARS), min_size=4, max_size=4),
                           hnp.arrays(st.sampled_from([np.int64, np.float64, np.bool_]), st.integers(0, 6)))


@settings(max_examples=60)
@given(seed=SEEDS, options=OPTIONS, actions=VECTOR_ACTIONS)
def test_the_vector_env_resets_and_steps_or_names_the_bad_value(vector_env, seed, options, actions):
    try:
        observations, infos = vector_env.reset(seed=seed, options=options)
    except ValueError as error:
        assert_one_line_naming(error, ("seed", "options", *SCENARIO_VALUES))
        observations, infos = vector_env.reset(seed=0)
    assert observations.shape == (4, 23) and observations.dtype == np.float32 and np.isfinite(observations).all()
    assert vector_env.observation_space.contains(observations)
    try:
        observations, rewards, terminated, truncated, infos = vector_env.step(actions)
    except ValueError as error:
        assert_one_line_naming(error, ("actions",))
        observations, rewards, terminated, truncated, infos = vector_env.step(np.zeros(4, np.int64))
    assert observations.shape == (4, 23) and np.isfinite(observations).all()
    assert vector_env.observation_space.contains(observations)
    assert rewards.shape == (4,) and np.isfinite(rewards).all()
    assert terminated.dtype == bool and not truncated.any()


# ---------------------------------------------------------------------------- the command line
def leaf_keys(config_name: str) -> list[str]:
    """Every dotted key of a composed root config (``ppo.num_envs``, ``task.speed``, ...) and its groups."""
    container = OmegaConf.to_container(compose_config(config_name=config_name), resolve=False)

    def walk(node, prefix):
        for key, value in node.items():
            path = f"{prefix}{key}"
            yield path
            if isinstance(value, dict):
                yield from walk(value, f"{path}.")

    return sorted(set(walk(container, "")))


TRAIN_KEYS, EVALUATE_KEYS = leaf_keys("config"), leaf_keys("evaluate")
JUNK_KEYS = ["sped", "ppo.num_env", "task.nme", "zz_junk", "a.b.c", "experiment", "hydra", "é", " seed", "",
             "checkpoint", "resume", "method.baseline", "output_dir"]
VALUES = st.one_of(
    st.integers(-10, 10**6).map(str), st.integers().map(str), st.floats().map(repr),
    st.sampled_from(["", "null", "true", "nan", "inf", "-inf", "1e400", "[1,2]", "[]", "[64,64]", "{a:1}", "${foo}",
                     "${seed}", "${oc.env:HOME}", "${now:}", "'", '"', "a=b", "a,b", "uniform", "curved", "fixed",
                     "irregular", "pretrained", "reuse", "scratch", "baseline", "no/such.pt", "r" * 300,
                     "/dev/null/x", f"{'o' * 300}/x", "cuda:7", "relative", "absolute", "glob(*)", "range(0,3)"]),
    st.text(st.characters(codec="utf-8", exclude_categories=["Cs"]), max_size=6),
)


def arguments(keys: list[str]) -> st.SearchStrategy:
    """1 to 3 command-line arguments: ``[+|~|++]key=value`` of real and mistyped keys, or any text at all."""
    override = st.builds(lambda prefix, key, value: f"{prefix}{key}={value}",
                         st.sampled_from(["", "", "", "+", "~", "++"]), st.sampled_from(keys + JUNK_KEYS), VALUES)
    return st.lists(st.one_of(override, override, st.text(max_size=8), st.just("-m")), min_size=1, max_size=3)


def names_an_argument(message: str, command: list[str]) -> bool:
    """The message names one of the arguments: the whole override, its key, or its value."""
    for argument in command:
        key, _, value = argument.partition("=")
        shown = (argument, override_key(argument), value.strip("'\" "), repr(argument), repr(argument)[1:-1])
        if any(text and text in message for text in shown):
            return True
    return "is required" in message  # checkpoint= left out: it names the key to give


@pytest.fixture(scope="module")
def entry_points():
    """{program: (config name, the entry point's input check)} as their ``__main__`` passes them to run_checked."""
    from agrl import evaluate, train

    return {"agrl.train": ("config", train.check_inputs), "agrl.evaluate": ("evaluate", evaluate.check_inputs)}


@pytest.fixture(scope="module")
def empty_folder(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cli_inputs_cwd")


def check_command_line(entry_points, folder: Path, program: str, command: list[str]) -> None:
    """Run the pre-Hydra checks of ``program`` on ``command`` in ``folder``: either the run would start, or exit 2
    with one stderr line naming an argument, and nothing written."""
    config_name, inputs = entry_points[program]
    started, stderr, argv = [], io.StringIO(), sys.argv
    sys.argv = [program, *command]
    try:
        with contextlib.chdir(folder), contextlib.redirect_stderr(stderr):
            run_checked(lambda: started.append(True), program, config_name, inputs)
        code = 0
    except SystemExit as exit_:
        code = exit_.code
    finally:
        sys.argv = argv
    written = sorted(path.name for path in folder.iterdir())
    for path in folder.iterdir():  # an accepted evaluation creates its output_dir: leave the folder empty
        shutil.rmtree(path) if path.is_dir() else path.unlink()
    if started:
        assert code == 0 and stderr.getvalue() == "", stderr.getvalue()
        return
    lines = stderr.getvalue().splitlines()
    assert code == 2 and len(lines) == 1, (code, lines)
    assert lines[0].startswith(f"{program}: error: "), lines[0]
    assert names_an_argument(lines[0], command), lines[0]
    assert written == [], written


@settings(max_examples=40)
@given(command=arguments(TRAIN_KEYS))
def test_train_command_lines_start_or_stop_with_one_line_naming_the_argument(entry_points, empty_folder, command):
    check_command_line(entry_points, empty_folder, "agrl.train", command)


@settings(max_examples=30)
@given(command=arguments(EVALUATE_KEYS), with_checkpoint=st.booleans())
def test_evaluate_command_lines_start_or_stop_with_one_line_naming_the_argument(entry_points, empty_folder, command,
                                                                              with_checkpoint):
    check_command_line(entry_points, empty_folder, "agrl.evaluate",
                       ["checkpoint=baseline", *command] if with_checkpoint else command)


def test_the_checks_refuse_what_hydra_would_not_say_in_one_line(entry_points, empty_folder):
    """Examples the properties found: each is refused before Hydra, with exit code 2 and one line naming it, and
    nothing is written in the working directory (where Hydra would write)."""
    for program, command, named in (
            ("agrl.train", ["a=b=c"], "a=b=c is not allowed: mismatched input '='"),
            ("agrl.train", [" "], "' ' is not allowed: not key=value in Hydra's override grammar"),
            ("agrl.train", ["seed=${foo}"], "seed=${foo} is not allowed: Interpolation key 'foo' not found"),
            ("agrl.train", ["resume=${oc.env:AGRL_NO_SUCH_VARIABLE}"], "resume=${oc.env:AGRL_NO_SUCH_VARIABLE} is not"),
            ("agrl.train", [f"resume={'r' * 300}"], f"resume={'r' * 300} is not allowed: File name too long"),
            ("agrl.train", ["method=reuse", f"method.baseline={'b' * 300}"], "method.baseline=bbb"),
            ("agrl.evaluate", [f"checkpoint={'c' * 300}"], "checkpoint=ccc"),
            ("agrl.evaluate", ["checkpoint=baseline", f"output_dir={'o' * 300}/x"],
             f"output_dir={'o' * 300}/x is not allowed: {'o' * 300}/x/eval.json: cannot be written: File name"),
    ):
        stderr, argv = io.StringIO(), sys.argv
        sys.argv = [program, *command]
        try:
            with contextlib.chdir(empty_folder), contextlib.redirect_stderr(stderr), pytest.raises(SystemExit) as exit_:
                run_checked(lambda: pytest.fail("the run started"), program, *entry_points[program])
        finally:
            sys.argv = argv
        assert exit_.value.code == 2
        assert stderr.getvalue().splitlines() == [stderr.getvalue().strip()], stderr.getvalue()
        assert stderr.getvalue().startswith(f"{program}: error: "), stderr.getvalue()
        assert named in stderr.getvalue(), stderr.getvalue()
        assert list(empty_folder.iterdir()) == []
