"""Hydra composition of conf/ and validation by agrl.config.load_config."""

from __future__ import annotations

import dataclasses
import math
import typing
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException, MissingConfigException
from omegaconf import MISSING
from omegaconf.errors import ValidationError

from agrl.config import (
    ActionsConfig,
    AgentConfig,
    ConfigError,
    CurriculumConfig,
    EvaluateConfig,
    EvaluationConfig,
    FinetuneConfig,
    InitialStateConfig,
    LimitsConfig,
    ManeuverConfig,
    MethodConfig,
    PPOConfig,
    RewardConfig,
    SimulationConfig,
    TaskConfig,
    ToleranceConfig,
    TrainConfig,
    compose_checked,
    guidance_parameters,
    load_config,
    task_label,
    to_guidance_parameters,
)
from agrl.core.aircraft import GRAVITY
from agrl.core.parameters import ACTION_FIELDS, DESTINATION_START, MOTION_FIELDS, ActionKind, DestinationMotion
from agrl.envs import GuidanceParameters, MotionKind

CONFIG_DIR = str((Path(__file__).resolve().parent.parent / "conf").resolve())


def compose_config(*overrides: str):
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def load(*overrides: str):
    return load_config(compose_config(*overrides))


def test_defaults_load():
    cfg = load()
    assert isinstance(cfg.task, TaskConfig)
    assert cfg.task.name == "fixed"
    assert cfg.simulation.integration_step == pytest.approx(0.02)
    assert cfg.simulation.decision_period == pytest.approx(3.0)


def test_uniform_speed_flows_into_task():
    cfg = load("task=uniform", "speed=50")
    assert cfg.task.name == "uniform"
    assert cfg.task.speed == 50.0
    assert load("task=uniform", "speed=10").task.speed == 10.0


def test_curved_radius_flows_into_task():
    cfg = load("task=curved", "radius=500")
    assert cfg.task.name == "curved"
    assert cfg.task.radius == 500.0
    assert cfg.task.speed == 20.0  # the paper's curved-motion speed
    params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False)
    assert params.destination.name is MotionKind.CURVED
    assert params.destination.radius == 500.0
    assert params.destination.turn_direction == 1.0 and isinstance(params.destination.turn_direction, float)
    assert params.compile is False
    assert params.simulation.tolerance.heading == pytest.approx(
        math.radians(cfg.simulation.tolerance.heading_deg)
    )


def test_switch_cost_is_off_in_the_papers_variants_and_reaches_the_env():
    for name in ("none", "continuous", "position", "both"):
        cfg = load(f"reward={name}")
        assert to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False).reward.switch_cost == 0.0
    # reward=switch: the position term and the cost (the continuous-action term off); the earlier form on request.
    cfg = load("reward=switch", "reward.switch_cost=0.7")
    params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False).reward
    assert (params.switch_cost, params.use_continuous_action, params.use_position) == (0.7, False, True)
    cfg = load("reward=switch", "reward.use_continuous_action=true")
    params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False).reward
    assert (params.switch_cost, params.use_continuous_action, params.use_position) == (0.1, True, True)


def test_switch_finetune_experiment_is_stage_two_of_the_baseline():
    """``+experiment=switch_finetune`` (the shipped baseline's stage 2) fine-tunes a fixed-destination agent at a
    larger switch cost, with stage 1's reward otherwise, for a fixed frame budget."""
    cfg = load("+experiment=switch_finetune", "method.baseline=somewhere")
    stage_one = load()
    assert (cfg.task.name, cfg.method.name, cfg.method.baseline) == ("fixed", "pretrained", "somewhere")
    assert cfg.reward.switch_cost > stage_one.reward.switch_cost
    assert cfg.reward.use_continuous_action == stage_one.reward.use_continuous_action
    assert cfg.target_success == 0 and cfg.ppo.max_minutes == 0
    assert cfg.ppo.total_frames % (cfg.ppo.num_envs * cfg.ppo.steps_per_env) == 0
    params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, compile=False)
    assert params.reward.switch_cost == cfg.reward.switch_cost


def test_switch_finetune_needs_the_stage_one_agent_named():
    """The shipped baseline is already stage 2's output, so the experiment does not default to it."""
    with pytest.raises(ConfigError, match="method.baseline=None"):
        load("+experiment=switch_finetune")


def test_fast_experiment_changes_only_the_measured_settings():
    """``+experiment=fast`` trains the fixed baseline's task and reward (with both shaping terms, as it was measured)
    with a narrower network, a larger learning rate and a cheaper, stricter stop; everything else
    stays the defaults."""
    fast, default = dict(_leaves(load("+experiment=fast"))), dict(_leaves(load()))
    changed = {key for key, value in fast.items() if default[key] != value}
    assert changed == {"agent.actor_hidden", "agent.critic_hidden", "ppo.learning_rate",
                       "target_success", "eval.interval", "eval.periodic_episodes", "eval.trajectory_image",
                       "eval.min_train_success", "reward.use_continuous_action"}
    assert fast["reward.use_continuous_action"] and not default["reward.use_continuous_action"]
    assert fast["target_success"] > default["target_success"]
    assert fast["eval.min_train_success"] < fast["target_success"]  # evaluations start before the stop can fire


def test_switch_schedule_experiment_fine_tunes_after_its_target_at_a_larger_cost():
    """``+experiment=switch_schedule`` (make train): the default task and reward on the searched settings, then a
    fine-tune in the same run at a larger switch cost; everything else stays the defaults."""
    schedule, default = dict(_leaves(load("+experiment=switch_schedule"))), dict(_leaves(load()))
    changed = {key for key, value in schedule.items() if default[key] != value}
    assert changed == {"agent.actor_hidden", "agent.critic_hidden", "ppo.learning_rate", "ppo.minibatch_size",
                       "ppo.num_envs", "ppo.steps_per_env", "ppo.compiled_entropy_draw",
                       "reward.switch_cost", "target_success", "finetune.iterations", "finetune.switch_cost",
                       "finetune.learning_rate",
                       "eval.interval", "eval.min_train_success", "eval.trajectory_image", "threads"}
    assert schedule["finetune.iterations"] > 0 and schedule["target_success"] > 0  # the target starts the fine-tune
    assert schedule["finetune.switch_cost"] > schedule["reward.switch_cost"]
    # The same decisions per batch as the defaults, in fewer, wider env steps.
    assert (schedule["ppo.num_envs"] * schedule["ppo.steps_per_env"]
            == default["ppo.num_envs"] * default["ppo.steps_per_env"])


def test_unknown_task_names_the_value():
    with pytest.raises(MissingConfigException) as info:
        load("task=bogus")
    lines = str(info.value).splitlines()
    assert lines[0] == "In 'config': Could not find 'task/bogus'"
    assert lines[2:7] == ["Available options in 'task':", "\tcurved", "\tfixed", "\tirregular", "\tuniform"]


@pytest.mark.parametrize(("overrides", "message"), [
    (("task=bogus",), "task=bogus is not allowed: one of curved, fixed, irregular, uniform"),
    (("task=uniform", "bogus=1"), "bogus=1 is not allowed: the config has no key 'bogus'; its keys: task, reward, "),
    (("task=uniform", "speed=-5"), "speed=-5.0 is not allowed: task=uniform needs a destination speed in (0, 1000]"),
    (("task=uniform", "speed=1e20"), "speed=1e+20 is not allowed: task=uniform needs a destination speed in (0, 1000]"),
    (("task=curved", "radius=1e12"), "radius=1000000000000.0 is not allowed: task=curved needs a turning radius in "),
    (("actions=bogus",), "actions=bogus is not allowed: one of maneuvers, targets"),
    (("actions=targets", "reward=both"), "reward.use_continuous_action=True is not allowed: false with "
                                         "actions=targets"),
    (("actions=targets", "actions.cruise_speed=300"), "actions.cruise_speed=300.0 is not allowed: within "
                                                      "simulation.limits [100.0, 250.0] m/s"),
    (("actions=targets", "actions.lowest_altitude=600"), "actions.lowest_altitude=600.0 is not allowed: in (0.0, "
                                                         "500.0) m"),
    (("actions=targets", "actions.headings=1"), "actions.headings=1 is not allowed: an integer in [2, 360]"),
    (("actions=targets", "actions.capture_fraction=0"), "actions.capture_fraction=0.0 is not allowed: (0, 1]"),
    (("actions=targets", "actions.speed_time_constant=-1"), "actions.speed_time_constant=-1.0 is not allowed: > 0 s"),
])
def test_guidance_parameters_refuse_overrides_as_the_command_line_does(overrides, message):
    # The README's `guidance_parameters("task=curved", ...)`: "overrides as on the command line", errors too.
    with pytest.raises(ConfigError) as raised:
        guidance_parameters(*overrides)
    assert str(raised.value).startswith(message) and "\n" not in str(raised.value)
    with pytest.raises(ConfigError) as raised:  # the training config's own check, before a run starts
        load_config(compose_checked(*overrides))
    assert str(raised.value).startswith(message)


def test_unknown_task_name_in_group_is_a_config_error():
    with pytest.raises(ConfigError, match="bogus"):
        load("task=uniform", "speed=50", "task.name=bogus")


def test_negative_uniform_speed_fails():
    with pytest.raises(ConfigError, match=r"speed=-5") as info:
        load("task=uniform", "speed=-5")
    assert "\n" not in str(info.value)


def test_zero_curved_radius_fails():
    with pytest.raises(ConfigError, match=r"radius=0") as info:
        load("task=curved", "radius=0")
    assert "\n" not in str(info.value)


def test_wrong_type_names_the_value():
    with pytest.raises(ConfigCompositionException, match=r"^Error merging override speed=abc$") as info:
        load("task=uniform", "speed=abc")
    cause = info.value.__cause__
    assert isinstance(cause, ValidationError)
    assert str(cause).splitlines()[0] == "Value 'abc' of type 'str' could not be converted to Float"


@pytest.mark.parametrize(
    "overrides,named",
    [
        (("reward.gamma=1.5",), "reward.gamma"),
        (("reward=switch", "reward.switch_cost=-0.1"), "reward.switch_cost"),
        (("simulation.decision_period=3.01",), "simulation.decision_period"),
        (("simulation.limits.min_speed=300",), "simulation.limits.min_speed"),
        (("simulation.initial_state.x_range=[-20000,0]",), "simulation.initial_state.x_range"),
        (("ppo.minibatch_size=100000000",), "ppo.minibatch_size"),
        (("threads=0",), "threads=0"),
        (("eval.min_train_success=1.5",), "eval.min_train_success"),
        (("ppo.target_kl=-0.01",), "ppo.target_kl"),
        (("task=irregular", "task.change_probability=2"), "task.change_probability"),
        (("method=reuse", "method.keep=middle"), "method.keep='middle'"),
        (("method=reuse", "method.max_candidates=many"), "method.max_candidates='many'"),
        (("method=reuse", "ppo.collector_workers=2"), "ppo.collector_workers=2"),
        (("method=pretrained", "method.baseline=null"), "method.baseline=None"),
        (("simulation.initial_state.min_horizontal_distance=900",), "simulation.initial_state.min_horizontal_distance"),
        (("search.success=0",), "search.success=0.0"),
        (("search.max_instructions=-1",), "search.max_instructions=-1.0"),
        (("search.penalty_seconds=-60",), "search.penalty_seconds=-60.0"),
        (("search.seeds=0",), "search.seeds=0"),
        (("search.seeds=3", "resume=runs/x"), "search.seeds=3 is not allowed: 1 with resume"),
        (("finetune.iterations=-1",), "finetune.iterations=-1"),
        (("finetune.learning_rate=0",), "finetune.learning_rate=0.0"),
        (("finetune.iterations=20", "target_success=0"), "finetune.iterations=20 is not allowed: 0 when target_su"),
        (("finetune.iterations=20", "ppo.collector_workers=2"), "finetune.iterations=20 is not allowed: 0 with ppo.co"),
        (("finetune.iterations=20", "finetune.switch_cost=20"), "finetune.switch_cost=20.0 is not allowed: < reward"),
    ],
)
def test_config_errors_are_one_line_and_name_the_key(overrides, named):
    with pytest.raises(ConfigError) as info:
        load(*overrides)
    message = str(info.value)
    assert named in message
    assert "\n" not in message


@pytest.mark.parametrize("method", ["scratch", "pretrained"])
def test_a_knob_of_another_method_is_one_line_naming_the_keys_this_one_has(method):
    # Each method has its own schema: reuse's knobs are not keys of the others.
    with pytest.raises(ConfigError) as info:
        compose_checked(f"method={method}", "method.start_from_baseline=true")
    keys = {"scratch": "name, use_curriculum, baseline", "pretrained": "name, baseline, use_curriculum"}[method]
    assert str(info.value) == ("method.start_from_baseline=true is not allowed: method has no key "
                               f"'start_from_baseline'; its keys: {keys}")


def test_task_label_names_the_motion_parameters():
    assert task_label(TaskConfig(name="uniform", speed=50.0)) == "uniform 50 m/s"
    curved = TaskConfig(name="curved", speed=20.0, radius=500.0, turn_direction=1)
    assert task_label(curved) == "curved 20 m/s, radius 500 m"
    assert task_label(TaskConfig(name="fixed")) == "fixed"


def test_unavailable_cuda_device_is_one_line_naming_what_is_available():
    import torch

    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    missing = f"cuda:{count}"  # one past the last device this machine has (cuda:0 on a CPU-only build)
    available = ", ".join(["cpu"] + [f"cuda:{index}" for index in range(count)])
    with pytest.raises(ConfigError) as info:
        load(f"device={missing}")
    expected = f"device={missing!r} is not allowed: this machine has {available} (torch {torch.__version__})"
    assert str(info.value) == expected


@pytest.mark.parametrize("device", ["gpu", "cuda:x", "cuda0"])
def test_malformed_device_is_refused(device):
    with pytest.raises(ConfigError, match=rf"device='{device}' is not allowed: cpu, cuda or cuda:N"):
        load(f"device={device}")


SCHEMAS = [TaskConfig, ActionsConfig, RewardConfig, SimulationConfig, ToleranceConfig, LimitsConfig, ManeuverConfig,
           InitialStateConfig, AgentConfig, PPOConfig, MethodConfig, EvaluationConfig, CurriculumConfig,
           FinetuneConfig, TrainConfig,
           EvaluateConfig]


@pytest.mark.parametrize("schema", SCHEMAS, ids=lambda schema: schema.__name__)
def test_schemas_hold_no_values_of_their_own(schema):
    """conf/*.yaml is the one source of values: a schema field is MISSING, or None where a task or method
    does not use it (EvaluateConfig.task: None = the checkpoint's own task)."""
    for spec in dataclasses.fields(schema):
        assert spec.default_factory is dataclasses.MISSING, spec.name
        assert spec.default in (MISSING, None), (schema.__name__, spec.name, spec.default)


def _leaves(record, prefix=""):
    for spec in dataclasses.fields(record):
        value = getattr(record, spec.name)
        if dataclasses.is_dataclass(value):
            yield from _leaves(value, f"{prefix}{spec.name}.")
        else:
            yield f"{prefix}{spec.name}", value


def test_every_task_value_comes_from_conf():
    """Two configs that differ in every conf value give records that differ in every field but the two
    conf does not set (gravity, the destination's start) and the task kind (both curved): no record field
    is left to its own default."""
    base = load("task=curved", "reward=both")
    changed = load("task=curved", "radius=700", "speed=30", "task.turn_direction=-1", "reward=switch",
                   "reward.use_continuous_action=false", "reward.use_position=false", "reward.success=21",
                   "reward.out_of_airspace=-21", "reward.budget_exhausted=-11", "reward.action_change=-0.2",
                   "reward.action_hold=-0.02", "reward.distance_weight=2e-4", "reward.heading_weight=0.6",
                   "reward.altitude_weight=2e-5", "reward.gamma=0.98", "reward.switch_cost=0.2",
                   "simulation.integration_step=0.05", "simulation.decision_period=2.0",
                   "simulation.max_decisions=150", "simulation.airspace.x_min=-11000", "simulation.airspace.x_max=9000",
                   "simulation.airspace.y_min=-9000", "simulation.airspace.y_max=11000",
                   "simulation.airspace.z_min=-100", "simulation.airspace.z_max=6000",
                   "simulation.tolerance.distance=900", "simulation.tolerance.altitude=150",
                   "simulation.tolerance.heading_deg=20", "simulation.limits.min_speed=90",
                   "simulation.limits.max_speed=260", "simulation.limits.max_flight_path_angle_deg=25",
                   "simulation.maneuvers.turn=2.5", "simulation.maneuvers.pull_up=2.5",
                   "simulation.maneuvers.push_over=-0.5",
                   "simulation.maneuvers.acceleration=0.2", "simulation.maneuvers.deceleration=0.25",
                   "simulation.initial_state.x_range=[-8000,6000]", "simulation.initial_state.y_range=[-8000,8000]",
                   "simulation.initial_state.z_range=[100,4000]", "simulation.initial_state.speed_range=[180,210]",
                   "simulation.initial_state.min_horizontal_distance=2500", "simulation.compile=false")
    irregular = load("task=irregular", "task.change_probability=0.3", "task.speed_range=[5,40]",
                     "task.max_turn_rate_deg=2.0")
    plain_irregular = load("task=irregular")
    first, second = (dict(_leaves(to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, actions=cfg.actions)))
                     for cfg in (base, changed))
    same = {path for path in first if first[path] == second[path]}
    # The irregular task's three values are unused by a curved destination: compare them on the irregular task.
    unused_by_curved = {"destination.change_probability", "destination.speed_range", "destination.max_turn_rate_deg"}
    # The action set's values: test_every_action_value_comes_from_conf.
    actions = {path for path in first if path.startswith("actions.")}
    assert same == {"simulation.gravity", "destination.start", "destination.name"} | unused_by_curved | actions
    destination, plain = (to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation).destination
                          for cfg in (irregular, plain_irregular))
    for name in ("change_probability", "speed_range", "max_turn_rate_deg"):
        assert None is not getattr(destination, name) != getattr(plain, name) is not None, name


def test_records_convert_units_and_types():
    cfg = load("task=irregular")
    params = to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation)
    assert params.destination.name is MotionKind.IRREGULAR
    assert params.destination.max_turn_rate_deg == cfg.task.max_turn_rate_deg
    assert params.destination.max_turn_rate == math.radians(cfg.task.max_turn_rate_deg)  # the radians used
    assert params.simulation.limits.max_flight_path_angle == math.radians(
        cfg.simulation.limits.max_flight_path_angle_deg)
    assert params.simulation.tolerance.heading == math.radians(cfg.simulation.tolerance.heading_deg)
    assert params.initial_state.x_range == tuple(cfg.simulation.initial_state.x_range)
    assert params.compile is cfg.simulation.compile
    assert params.reward.success == cfg.reward.success and params.reward.altitude_weight == cfg.reward.altitude_weight


#: The only record fields with a default, because conf/ holds no value for them.
ALLOWED_DEFAULTS = {
    ("SimulationParameters", "gravity"): GRAVITY,  # a physical constant, not a choice
    ("DestinationMotion", "start"): DESTINATION_START,  # the paper's Table 1, the same for every task
    # A destination field that only some kinds read is None for the others (DestinationMotion checks its own).
    **{("DestinationMotion", name): None for names in MOTION_FIELDS.values() for name in names},
    # Likewise an action-set field that only the target-holding actions read.
    **{("ActionSet", name): None for names in ACTION_FIELDS.values() for name in names},
}


def _record_types(record_type: type) -> list[type]:
    """``record_type`` and every record nested in it."""
    hints = typing.get_type_hints(record_type)
    nested = [hints[spec.name] for spec in dataclasses.fields(record_type)
              if dataclasses.is_dataclass(hints[spec.name])]
    return [record_type] + [inner for record in nested for inner in _record_types(record)]


def record_defaults(record_type: type) -> dict[tuple[str, str], object]:
    """``{(record name, field name): default}`` of every field of ``record_type`` (nested) that has one."""
    defaults = {}
    for record in _record_types(record_type):
        for spec in dataclasses.fields(record):
            if spec.default is not dataclasses.MISSING:
                defaults[record.__name__, spec.name] = spec.default
            elif spec.default_factory is not dataclasses.MISSING:
                defaults[record.__name__, spec.name] = spec.default_factory()
    return defaults


def test_the_records_hold_no_values_but_the_named_constants():
    """conf/ is the one source of each value: the env's records have no defaults of their own."""
    names = {record.__name__ for record in _record_types(GuidanceParameters)}
    assert names == {"GuidanceParameters", "SimulationParameters", "Airspace", "SuccessTolerance", "AircraftLimits",
                     "ManeuverLoadFactors", "RewardParameters", "InitialStateDistribution", "DestinationMotion",
                     "ActionSet"}
    assert record_defaults(GuidanceParameters) == ALLOWED_DEFAULTS


@dataclasses.dataclass(frozen=True)
class DefaultedInner:
    value: float = 1.5


@dataclasses.dataclass(frozen=True)
class DefaultedOuter:
    inner: DefaultedInner
    required: float
    count: int = dataclasses.field(default_factory=lambda: 3)


def test_a_record_default_is_found():
    """The check above can fail: a default (or default factory) on a nested record is reported."""
    assert record_defaults(DefaultedOuter) == {("DefaultedOuter", "count"): 3, ("DefaultedInner", "value"): 1.5}


def test_a_destination_needs_the_fields_its_kind_reads():
    with pytest.raises(ValueError, match=r"^DestinationMotion radius=None is not allowed: name=curved needs speed, "
                                         r"radius, turn_direction$"):
        DestinationMotion(name=MotionKind.CURVED, speed=20.0)
    assert DestinationMotion(name=MotionKind.FIXED).speed is None


def test_a_task_value_its_task_needs_is_required():
    with pytest.raises(ConfigError, match=r"^task.radius=None is not allowed: task=curved needs a value$"):
        load("task=curved", "task.radius=null")


def test_collector_workers_must_divide_the_envs():
    with pytest.raises(ConfigError, match=r"^ppo.collector_workers=3 is not allowed: a divisor of ppo.num_envs=512"):
        load("ppo.collector_workers=3")
    with pytest.raises(ConfigError, match=r"^ppo.collector_workers=2 is not allowed: 1 with method=reuse"):
        load("ppo.collector_workers=2", "method=reuse")
    with pytest.raises(ConfigError, match=r"^ppo.collector_workers=2 is not allowed: 1 with resume \(exact resume"):
        load("ppo.collector_workers=2", "resume=runs/some_run")
    assert load("ppo.collector_workers=2", "curriculum.enabled=false").ppo.collector_workers == 2
    assert load("ppo.collector_workers=2").curriculum.enabled  # the workers' envs follow the curriculum too


def _unread(record_type: type, values: dict, prefix: str = "") -> set[str]:
    """The keys of a config section (nested sections too) that name no field of ``record_type``."""
    hints = typing.get_type_hints(record_type)
    names = {spec.name for spec in dataclasses.fields(record_type)}
    unread = {f"{prefix}{key}" for key in values if key not in names}
    for name in names & set(values):
        if dataclasses.is_dataclass(hints[name]) and isinstance(values[name], dict):
            unread |= _unread(hints[name], values[name], f"{prefix}{name}.")
    return unread


def test_every_key_of_the_task_sections_is_a_record_field_of_the_same_name():
    """One name per value: the YAML key is the record field it sets (the converse of the test above), so the
    records are built by name (agrl.config.records.build_record). The reward's ``name`` only picks the YAML."""
    from omegaconf import OmegaConf

    from agrl.core.reward import RewardParameters
    from agrl.core.simulation import SimulationParameters

    config = OmegaConf.to_container(compose_config("task=irregular"), resolve=True)
    assert _unread(RewardParameters, config["reward"]) == {"name"}
    assert _unread(DestinationMotion, config["task"]) == set()
    simulation = config["simulation"]
    # GuidanceParameters takes the simulation section's records and values; its simulation record the rest.
    assert _unread(GuidanceParameters, simulation) == {"integration_step", "decision_period", "airspace", "tolerance",
                                                       "limits"}
    assert _unread(SimulationParameters, simulation) == {"max_decisions", "maneuvers", "initial_state", "compile"}


# ---------------------------------------------------------------------------- actions
def test_actions_default_to_the_papers_maneuvers_and_targets_reach_the_env():
    assert load().actions.name == "maneuvers"
    assert guidance_parameters().actions.name is ActionKind.MANEUVERS and guidance_parameters().num_actions == 7
    params = guidance_parameters("actions=targets", "actions.headings=8", "actions.altitude_step=1000",
                                 "actions.heading_time_constant=3")
    actions = params.actions
    assert actions.holds_targets and actions.headings == 8 and actions.altitude_step == 1000.0
    assert params.num_actions == 1 + 8 + (1 + 4) + 3  # hold, headings, 100 m and 1000..4000 m, speeds
    assert actions.autopilot(params.maneuvers).heading_time_constant == 3.0
    assert actions.autopilot(params.maneuvers).turn_load_factor == params.maneuvers.turn


def test_a_saved_config_without_actions_flies_the_papers_maneuvers():
    from omegaconf import OmegaConf

    from agrl.config import saved_guidance_parameters

    saved = OmegaConf.to_container(compose_config("actions=targets"), resolve=True)  # as a checkpoint saves it
    assert saved_guidance_parameters(saved).actions.holds_targets
    del saved["actions"]
    assert saved_guidance_parameters(saved).actions.name is ActionKind.MANEUVERS


def test_every_action_value_comes_from_conf():
    base = load("actions=targets")
    changed = load("actions=targets", "actions.headings=8", "actions.altitude_step=1000", "actions.lowest_altitude=150",
                   "actions.cruise_speed=180", "actions.heading_time_constant=3", "actions.altitude_time_constant=6",
                   "actions.flight_path_time_constant=1.5", "actions.speed_time_constant=4",
                   "actions.capture_fraction=0.6")
    first, second = (to_guidance_parameters(cfg.task, cfg.reward, cfg.simulation, actions=cfg.actions).actions
                     for cfg in (base, changed))
    same = {spec.name for spec in dataclasses.fields(first) if getattr(first, spec.name) == getattr(second, spec.name)}
    assert same == {"name"}
