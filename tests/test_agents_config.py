"""Presets resolve to the documented numbers; configurations round-trip; imports stay light."""

import dataclasses
import subprocess
import sys

import pytest

from pianist.agents import PRESETS, TrainConfig, get_preset


def test_droq_paper_is_the_papers_recipe():
    cfg = get_preset("droq-paper")
    a, t = cfg.agent, cfg.task
    assert a.hidden_dims == (256, 256, 256)
    assert a.activation == "gelu"
    assert a.critic_dropout == 0.01 and a.critic_layer_norm
    assert a.num_qs == 2 and a.num_min_qs is None
    assert a.discount == 0.8
    assert a.actor_lr == a.critic_lr == a.temp_lr == 3e-4
    assert a.batch_size == 256
    assert a.tau == 0.005 and a.init_temperature == 1.0
    assert a.target_entropy_per_dim == -0.5
    assert (a.log_std_min, a.log_std_max) == (-20.0, 2.0)
    assert cfg.seed_steps == 5000
    assert cfg.updates_per_step == 1 and cfg.steps_per_iteration == 1 and not cfg.pipeline
    assert cfg.replay_capacity == 1_000_000
    assert cfg.eval_interval == 10_000
    assert t.lookahead == 10 and t.hands == "both" and t.physics == "faithful"
    assert t.reduced_action_space and t.gravity_compensation and t.primitive_fingertip_collisions
    assert t.action_reward_observation
    assert t.goal_frames_observed is None and t.finger_target_frames == 0 and not t.residual


def test_the_other_presets_change_only_what_they_say():
    paper = get_preset("droq-paper")
    pipelined = get_preset("droq-paper-pipelined")
    assert pipelined.agent == paper.agent and pipelined.task == paper.task
    assert pipelined.pipeline and pipelined.steps_per_iteration == 10
    redq = get_preset("redq")
    assert (redq.agent.num_qs, redq.agent.num_min_qs, redq.updates_per_step) == (10, 2, 20)
    fast = get_preset("fast")
    assert fast.task.hands == "song" and fast.task.finger_target_frames > 0
    assert fast.agent.critic_dropout == 0.01 and fast.agent.discount == 0.8
    residual = get_preset("residual")
    assert residual.task.residual and 0 < residual.task.residual_scale <= 1


def test_the_anchored_residual_starts_as_the_planner_and_stays_near_it():
    anchored, residual = get_preset("residual-anchored"), get_preset("residual")
    assert anchored.task == residual.task  # same scene: the planner's, scale 0.3
    a = anchored.agent
    assert a.zero_mean_init and a.init_log_std == -2.3 and a.log_std_max == -1.5
    assert a.target_entropy_per_dim == -1.0 and a.init_temperature == 0.1
    assert a.actor_lr == 1e-4 and a.critic_lr == 3e-4 and a.residual_penalty == 0.5
    assert anchored.seed_policy == "actor" and anchored.seed_steps == 1000
    assert anchored.eval_interval == 2000
    # Everything else is the fast preset's.
    fast = get_preset("fast").agent
    assert (a.hidden_dims, a.batch_size, a.discount, a.critic_dropout) == (
        fast.hidden_dims,
        fast.batch_size,
        fast.discount,
        fast.critic_dropout,
    )
    # The other presets keep the original initialisation and seed steps.
    for name in ("droq-paper", "fast", "residual"):
        cfg = get_preset(name)
        assert not cfg.agent.zero_mean_init and cfg.agent.init_log_std is None
        assert cfg.agent.residual_penalty == 0 and cfg.seed_policy == "uniform"


def test_the_residual_task_is_the_environment_the_planner_asks_for():
    from pianist.control.planner import IKPlanner

    wanted = IKPlanner().env_options()
    assert wanted["forearm_dofs"] == ("tx", "ty", "tz")
    for name in ("residual", "residual-anchored"):
        options = get_preset(name).task.env_options(("right",))
        for key, value in wanted.items():
            assert options[key] == value
    assert get_preset("fast").task.env_options(("right",))["forearm_dofs"] == ("tx", "ty")


@pytest.mark.parametrize("name", list(PRESETS))
def test_configs_round_trip_through_dicts(name):
    cfg = PRESETS[name]
    assert TrainConfig.from_dict(cfg.to_dict()) == cfg
    assert cfg.preset == name


def test_bad_presets_and_fields_are_clear_errors():
    with pytest.raises(ValueError, match="unknown preset"):
        get_preset("droq-papr")
    with pytest.raises(ValueError, match="bad override"):
        get_preset("fast", no_such_field=1)
    with pytest.raises(ValueError, match="num_min_qs"):
        dataclasses.replace(get_preset("redq").agent, num_min_qs=11)
    with pytest.raises(ValueError, match="seed_policy"):
        get_preset("residual-anchored", seed_policy="planner")
    with pytest.raises(ValueError, match="init_log_std"):
        dataclasses.replace(get_preset("fast").agent, init_log_std=5.0)
    with pytest.raises(ValueError, match="residual_penalty"):
        dataclasses.replace(get_preset("fast").agent, residual_penalty=-1.0)
    with pytest.raises(ValueError, match="not a training configuration"):
        TrainConfig.from_dict({"task": {}})


def test_importing_the_agents_package_does_not_load_jax():
    code = "import sys, pianist, pianist.agents, pianist.agents.policy; print('jax' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False"]


def test_a_task_can_give_the_hands_a_lead_in():
    from pianist.agents.envs import make_agent_env

    cfg = get_preset("fast")
    task = dataclasses.replace(cfg.task, initial_buffer_s=0.5)
    env = make_agent_env("twinkle-twinkle", task)
    plain = make_agent_env("twinkle-twinkle", cfg.task)
    assert env.unwrapped.goal.num_frames == plain.unwrapped.goal.num_frames + 10
    assert not env.unwrapped.goal.keys[:10].any()
    restored = TrainConfig.from_dict(dataclasses.replace(cfg, task=task).to_dict())
    assert restored.task.initial_buffer_s == 0.5


def test_train_and_sweep_default_to_practice():
    from pianist.agents.config import DEFAULT_PRESET
    from pianist.cli.train import Train
    from pianist.sweep.tasks import TASKS

    assert DEFAULT_PRESET == "practice"
    assert Train().preset == DEFAULT_PRESET
    assert TASKS["train"].default_variant == DEFAULT_PRESET
    with pytest.raises(ValueError, match="not a soft actor-critic preset"):
        get_preset(DEFAULT_PRESET)
