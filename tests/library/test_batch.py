"""The kit's batch engine (hwlib/machinery/batch.py, hwlib/training.py): faster, never different, and it stops when asked."""

import _thread
import signal
import threading
import time

import numpy as np
import pytest

from hwlib import CartPoleLinearPolicy, TodoNotDone, policy_search, settings
from hwlib import cartpole
from hwlib.cartpole import make_env, play_episode, random_policy_rewards
from hwlib.machinery import batch as _batch
from hwlib.machinery import episodes as _episodes
from hwlib.machinery.episodes import run_episodes
from hwlib.training import TooSlow, learning_rate_sweep, run_training

PARAMS = [0.1, -0.3, -0.9, -0.2]


def plain_mean(policy, seeds):
    return float(np.mean([play_episode(policy, seed=seed).total_reward for seed in seeds]))


def session_replaying(**options):
    """A session, and the context in which its runs' ``policy_search.run_policy``, ``eval_params`` and
    ``scalar_finite_diff`` are the session's (what ``hwlib/training.py`` does)."""
    session = _batch.Session(**options)
    return session, session.replaying(policy_search, ("eval_params", "scalar_finite_diff"), counted="eval_params")


def run_policy(policy, seed=None):
    """``run_policy`` as the code in hwlib/policy_search.py finds it: by the module's name, where the kit's
    runs put the session's in its place."""
    return policy_search.run_policy(policy, seed=seed)


# Three ways a student writes eval_params, all correct: the docstring's seeds, seeds from a
# generator, no seeds at all. Each is put in place of the kit's with monkeypatch.

def eval_seed_plus_k(params, num_rollouts=20, seed=0):
    policy = CartPoleLinearPolicy(params)
    return float(np.mean([run_policy(policy, seed=seed + k) for k in range(num_rollouts)]))


def eval_generator(params, num_rollouts=20, seed=0):
    policy = CartPoleLinearPolicy(params)
    draws = np.random.default_rng(seed).integers(0, 2**31 - 1, size=num_rollouts)
    return float(np.mean([run_policy(policy, seed=int(s)) for s in draws]))


def eval_unseeded(params, num_rollouts=20, seed=0):
    policy = CartPoleLinearPolicy(params)
    return float(np.mean([run_policy(policy) for _ in range(num_rollouts)]))


STYLES = {"seed + k": eval_seed_plus_k, "generator": eval_generator, "unseeded": eval_unseeded}


@pytest.mark.parametrize("style", ["seed + k", "generator"])
def test_one_evaluation_is_played_in_one_batch_of_exactly_its_episodes(monkeypatch, style):
    monkeypatch.setattr(policy_search, "eval_params", STYLES[style])
    session, replaying = session_replaying()
    with replaying:
        [value] = session.run([lambda: policy_search.eval_params(PARAMS, num_rollouts=6, seed=40)])
    assert (session.rounds, session.episodes_played) == (1, 6)  # recorded once, played once, nothing else
    assert value == STYLES[style](PARAMS, num_rollouts=6, seed=40)  # the plain call
    assert policy_search.eval_params is STYLES[style]  # put back after the run


def test_unseeded_episodes_start_where_the_runs_own_env_resets_batched_or_not(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_unseeded)
    results = {}
    for batched in (True, False):
        session, replaying = session_replaying(batched=batched)
        with replaying:
            results[batched] = session.run([lambda: policy_search.eval_params(PARAMS, num_rollouts=6)] * 2,
                                           env_seeds=[7, 8])
        assert session.episodes_played == 12
    assert results[True] == results[False]
    # Run 0's episodes: an environment reset with seed 7, then reset() five more times (gymnasium's own stream).
    env, policy = make_env(), CartPoleLinearPolicy(PARAMS)
    rewards = [play_episode(policy, seed=7 if k == 0 else None, env=env).total_reward for k in range(6)]
    assert results[True][0] == float(np.mean(rewards))


@pytest.mark.parametrize("style", list(STYLES))
def test_the_sweep_equals_the_plain_loop_whatever_the_seeding(monkeypatch, style):
    monkeypatch.setattr(policy_search, "eval_params", STYLES[style])
    options = {"learning_rates": [0.0005, 0.002], "num_seeds": 2, "first_seed": 3, "num_training_iterations": 3,
               "num_rollouts_per_eval": 5, "progress": False}
    batched = learning_rate_sweep(**options)
    looped = learning_rate_sweep(**options, batched=False)
    np.testing.assert_array_equal(batched.rewards, looped.rewards)
    assert len(np.unique(batched.rewards)) > 3  # real curves, not one value
    np.testing.assert_array_equal(learning_rate_sweep(**options).rewards, batched.rewards)  # and every time the same


def test_a_sweep_run_is_the_training_run_alone(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_unseeded)
    sweep = learning_rate_sweep([0.001], num_seeds=2, first_seed=4, num_training_iterations=2, progress=False)
    alone = run_training(2, learning_rate=0.001, seed=5, progress=False)
    np.testing.assert_array_equal(sweep.rewards[0, 1], alone.rewards)


def test_a_training_run_needs_two_batches_per_iteration():
    session, replaying = session_replaying()
    with replaying:
        [run] = session.run([lambda: policy_search.train_cartpole_policy(3, 5, 0.001, seed=2)])
    assert session.rounds == 1 + 2 * 3  # g(θ₀); then per iteration the 8 neighbours together, and g(θ_t+1)
    assert session.episodes_played == (1 + 9 * 3) * 5
    plain = policy_search.train_cartpole_policy(3, 5, 0.001, seed=2)  # outside a kit run: the plain loop
    np.testing.assert_array_equal(run.rewards, plain.rewards)
    assert policy_search.run_policy is cartpole.run_policy  # the module's own again, after the run


def test_code_that_asks_for_episodes_one_at_a_time_still_gets_the_right_rewards():
    policy = CartPoleLinearPolicy([0.2, 0.1, -1.0, -0.3])
    session, replaying = session_replaying()
    with replaying:
        rewards = session.run([lambda seed=seed: run_policy(policy, seed=seed) for seed in (3, 99, 3, 7)])
    assert rewards == [play_episode(policy, seed=seed).total_reward for seed in (3, 99, 3, 7)]
    assert session.episodes_played == 3  # through the session: seed 3's episode played once


class MirroredPolicy(CartPoleLinearPolicy):
    """Not equation (1): the batch engine's copy of it must not be used for this policy."""

    def __call__(self, obs):
        return int(np.dot(self.params, obs) > 0)


class TieBreakingPolicy(CartPoleLinearPolicy):
    """Equation (1) but for the tie at zero, where it pushes right."""

    def __call__(self, obs):
        return int(np.dot(self.params, obs) <= 0)


class FarOffPolicy(CartPoleLinearPolicy):
    """Equation (1) near the start states, something else far out: only the wider check sees it."""

    def __call__(self, obs):
        if abs(float(obs[1])) > 1.5:
            return 1
        return int(np.dot(self.params, obs) < 0)


@pytest.mark.parametrize("policy_class", [MirroredPolicy, TieBreakingPolicy, FarOffPolicy])
def test_a_policy_that_is_not_equation_one_is_played_with_its_own_call(policy_class):
    params = [0.0, 0.0, 0.0, 0.0] if policy_class is TieBreakingPolicy else [0.3, -0.2, 0.8, 0.1]
    policy = policy_class(params)
    assert not _episodes.agrees_with_equation_one(policy, np.array(params, dtype=float))
    session, replaying = session_replaying()
    with replaying:
        batched = session.run([lambda seed=seed: run_policy(policy, seed=seed) for seed in range(4)])
    assert batched == [play_episode(policy, seed=seed).total_reward for seed in range(4)]
    assert session.step_by_step == 4


def test_random_policies_and_the_landscape_play_the_students_policy(monkeypatch):
    monkeypatch.setattr(CartPoleLinearPolicy, "__call__", MirroredPolicy.__call__)
    params, rewards = random_policy_rewards(30, seed=1)
    looped = [play_episode(CartPoleLinearPolicy(p), seed=int(s)).total_reward
              for p, s in zip(params, np.random.default_rng(2).integers(0, 2**31 - 1, size=30))]
    np.testing.assert_array_equal(rewards, looped)
    monkeypatch.undo()
    assert not np.array_equal(random_policy_rewards(30, seed=1)[1], rewards)  # equation (1) plays other episodes


def test_an_error_in_the_policy_reaches_the_caller():
    class Broken(CartPoleLinearPolicy):
        def __call__(self, obs):
            raise RuntimeError("broken policy")

    session, replaying = session_replaying()
    with pytest.raises(RuntimeError, match="broken policy"), replaying:
        session.run([lambda: run_policy(Broken([0.0, 0.0, 0.0, 0.0]), seed=1)])


def stub_call(self, obs):
    raise TodoNotDone("1.1.1")


def stub_eval_params(params, num_rollouts=20, seed=0):
    raise TodoNotDone("1.3.1")


@pytest.mark.parametrize("work", ["sweep", "training", "random policies", "landscape", "run_episodes"])
def test_a_todo_not_done_comes_through_the_kit_as_itself(monkeypatch, work):
    monkeypatch.setattr(CartPoleLinearPolicy, "__call__", stub_call)
    from hwlib.landscape import reward_slice

    calls = {
        "sweep": lambda: learning_rate_sweep([0.001, 0.002], num_seeds=2, num_training_iterations=2, progress=False),
        "training": lambda: run_training(2, learning_rate=0.001, progress=False),
        "random policies": lambda: random_policy_rewards(5, seed=0),
        "landscape": lambda: reward_slice(np.zeros(4), grid_size=3, num_episodes=2, progress=False),
        "run_episodes": lambda: run_episodes(np.zeros((2, 4)), [0, 1]),
    }
    with pytest.raises(TodoNotDone) as caught:
        calls[work]()
    assert type(caught.value) is TodoNotDone and caught.value.todo == "1.1.1"
    assert not [thread for thread in threading.enumerate() if thread.name.startswith("hwlib-run-")]


def test_a_todo_not_done_in_one_run_of_the_sweep_stops_them_all(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", stub_eval_params)
    with pytest.raises(TodoNotDone, match=r"TODO 1\.3\.1 is not done yet: eval_params in hwlib/policy_search\.py"):
        learning_rate_sweep([0.001, 0.002], num_seeds=3, progress=False)
    assert not [thread for thread in threading.enumerate() if thread.name.startswith("hwlib-run-")]
    assert policy_search.eval_params is stub_eval_params


def test_many_runs_asking_for_the_same_episodes_all_get_them():
    session, replaying = session_replaying()
    with replaying:
        results = session.run([lambda: policy_search.eval_params(PARAMS, num_rollouts=5, seed=2)] * 12)
    assert results == [plain_mean(CartPoleLinearPolicy(PARAMS), range(2, 7))] * 12
    assert session.episodes_played == 5


def test_runs_keep_their_order_and_the_first_error_is_raised():
    assert _batch.Session().run([lambda value=value: value * 2 for value in range(5)]) == [0, 2, 4, 6, 8]
    assert _batch.Session().run([]) == []

    def fails():
        raise ValueError("task failed")

    with pytest.raises(ValueError, match="task failed"):
        _batch.Session().run([lambda: 1, fails])


@pytest.fixture
def kernel_interrupt():
    """``interrupt()``: Kernel → Interrupt, a KeyboardInterrupt in the main thread, sent from another
    thread. A test run started in a shell's background ignores SIGINT, and ``interrupt_main`` then
    does nothing: the kernel's own handler, Python's default, is in place during the test."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield _thread.interrupt_main
    signal.signal(signal.SIGINT, previous)


def interrupt_when(event, interrupt):
    """A thread that interrupts the main thread once ``event`` is set (within two minutes, or never);
    call its ``cancel()`` when the work it interrupts is over."""
    cancelled = threading.Event()

    def watch():
        if event.wait(120) and not cancelled.is_set():
            interrupt()

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.cancel = cancelled.set
    watcher.start()
    return watcher


def run_threads_left(within=5.0):
    """The kit's run threads still alive once they had ``within`` seconds to end (a loaded machine is slow)."""
    deadline = time.monotonic() + within
    while True:
        left = [thread for thread in threading.enumerate() if thread.name.startswith("hwlib-run-")]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.05)


def interrupt_the_sweep(interrupt, monkeypatch, after_rounds=2, **options):
    """Send Kernel → Interrupt into the notebook's sweep once it has played ``after_rounds`` batches."""
    rounds, original = [], _batch.Session.play_round
    playing = threading.Event()

    def counting(self):
        rounds.append(1)
        if len(rounds) >= after_rounds:
            playing.set()
        return original(self)

    monkeypatch.setattr(_batch.Session, "play_round", counting)
    watcher = interrupt_when(playing, interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            learning_rate_sweep(settings.SWEEP_LEARNING_RATES, num_seeds=settings.SWEEP_NUM_SEEDS, progress=False,
                                max_minutes=None, **options)
    finally:
        watcher.cancel()
    assert playing.is_set()


@pytest.mark.timeout(300)
def test_kernel_interrupt_stops_the_sweep_and_leaves_no_thread_behind(kernel_interrupt, monkeypatch):
    interrupt_the_sweep(kernel_interrupt, monkeypatch)  # the benchmark times how soon it stops
    assert not run_threads_left()
    assert policy_search.eval_params.__module__ == "hwlib.policy_search" and not hasattr(policy_search.eval_params, "__wrapped__")
    assert policy_search.run_policy is cartpole.run_policy


@pytest.mark.timeout(300)
def test_interrupt_stops_a_run_busy_in_its_own_code(kernel_interrupt):
    spinning = threading.Event()

    def busy():
        spinning.set()
        while True:
            sum(range(1000))

    watcher = interrupt_when(spinning, kernel_interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            _batch.Session().run([busy, busy])
    finally:
        watcher.cancel()
    assert not run_threads_left()


def test_a_sweep_that_would_take_hours_says_so_before_it_starts(monkeypatch):
    monkeypatch.setattr(CartPoleLinearPolicy, "__call__", MirroredPolicy.__call__)
    started = time.monotonic()
    with pytest.raises(TooSlow, match=r"would take about .* so the kit did not start it.*step by step") as caught:
        learning_rate_sweep(progress=False)
    assert "equation (1) gives" in str(caught.value) and "max_minutes=None" in str(caught.value)
    assert caught.value._render_traceback_()[1].startswith("For example CartPoleLinearPolicy(")
    assert time.monotonic() - started < 30  # told before it runs: nothing of the sweep was played


def eval_global_generator(params, num_rollouts=20, seed=0):
    policy = CartPoleLinearPolicy(params)
    return float(np.mean([run_policy(policy, seed=int(np.random.randint(0, 2**31 - 1))) for _ in range(num_rollouts)]))


def test_code_that_draws_from_numpys_global_generator_gets_the_plain_loops_numbers(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_global_generator)
    runs = {}
    for batched in (True, False):
        np.random.seed(5)
        runs[batched] = run_training(3, 5, 0.001, seed=1, batched=batched, progress=False)
        runs[batched, "next draw"] = np.random.randint(1000)  # the global generator moved on as in the plain loop
    np.testing.assert_array_equal(runs[True].rewards, runs[False].rewards)
    assert runs[True, "next draw"] == runs[False, "next draw"]


def test_a_training_run_that_turns_out_slow_is_stopped_with_its_estimate(monkeypatch):
    # One run is never refused before it starts (it takes minutes at worst); once it has run a few
    # seconds, a projection beyond max_minutes stops it, naming the reason.
    monkeypatch.setattr(CartPoleLinearPolicy, "__call__", MirroredPolicy.__call__)
    with pytest.raises(TooSlow, match=r"This training run would take about .* so the kit stopped it after") as caught:
        run_training(learning_rate=0.001, progress=False, max_minutes=0.01)
    assert "step by step" in caught.value.second
    assert policy_search.eval_params.__module__ == "hwlib.policy_search" and not hasattr(policy_search.eval_params, "__wrapped__")


def eval_os_random(params, num_rollouts=20, seed=0):
    import os

    policy = CartPoleLinearPolicy(params)
    return float(np.mean([run_policy(policy, seed=int.from_bytes(os.urandom(3), "little")) for _ in range(num_rollouts)]))


def test_a_sweep_whose_episodes_cannot_be_foreseen_is_stopped_when_it_would_take_too_long(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_os_random)
    with pytest.raises(TooSlow, match=r"This learning-rate sweep would take about") as caught:
        learning_rate_sweep([0.001, 0.002], num_seeds=10, progress=False, max_minutes=0.01)
    assert "one at a time" in caught.value.second
    assert not [thread for thread in threading.enumerate() if thread.name.startswith("hwlib-run-")]


class counting:
    """eval_params that counts how often its code runs."""

    def __init__(self, function):
        self.function, self.calls = function, 0
        self.__signature__ = __import__("inspect").signature(function)

    def __call__(self, *args, **kwargs):
        self.calls += 1
        return self.function(*args, **kwargs)


@pytest.mark.parametrize("style", ["seed + k", "generator"])
def test_a_run_whose_seeds_follow_its_arguments_is_foreseen_not_recorded_twice(monkeypatch, style):
    student = counting(STYLES[style])
    monkeypatch.setattr(policy_search, "eval_params", student)
    run = run_training(4, 5, 0.001, seed=3, progress=False)
    evaluations = 1 + 9 * 4
    assert student.calls < 1.5 * evaluations  # recorded then replayed every time would be 2x
    monkeypatch.setattr(policy_search, "eval_params", STYLES[style])
    plain = policy_search.train_cartpole_policy(4, 5, 0.001, seed=3)
    np.testing.assert_array_equal(run.rewards, plain.rewards)


def eval_seeds_from_params(params, num_rollouts=20, seed=0):
    """Correct enough, but its seeds depend on the parameters too: foreseeing them goes wrong once."""
    policy = CartPoleLinearPolicy(params)
    shift = int(abs(float(np.sum(params))) * 1000) % 7
    return float(np.mean([run_policy(policy, seed=seed + shift + k) for k in range(num_rollouts)]))


def test_a_wrong_foresight_starts_the_call_again_and_changes_no_number(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_seeds_from_params)
    session, replaying = session_replaying()
    with replaying:
        [run] = session.run([lambda: policy_search.train_cartpole_policy(4, 5, 0.001, seed=3)])
    assert session.runs[0].memory.refuted
    plain = policy_search.train_cartpole_policy(4, 5, 0.001, seed=3)
    np.testing.assert_array_equal(run.rewards, plain.rewards)
    np.testing.assert_array_equal(run.params_history, plain.params_history)


def test_unseeded_code_is_foreseen_from_the_runs_own_env(monkeypatch):
    student = counting(eval_unseeded)
    monkeypatch.setattr(policy_search, "eval_params", student)
    session, replaying = session_replaying()
    with replaying:
        [run] = session.run([lambda: policy_search.train_cartpole_policy(4, 5, 0.001, seed=3)], env_seeds=[3])
    assert not session.runs[0].memory.refuted and student.calls < 1.5 * (1 + 9 * 4)
    assert session.episodes_played == (1 + 9 * 4) * 5  # nothing foreseen that was not asked for
    looped = run_training(4, 5, 0.001, seed=3, batched=False, progress=False)
    np.testing.assert_array_equal(run.rewards, looped.rewards)


def test_unseeded_episodes_of_a_policy_played_step_by_step_equal_the_plain_loop(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_unseeded)
    monkeypatch.setattr(CartPoleLinearPolicy, "__call__", MirroredPolicy.__call__)
    options = {"learning_rates": [0.0005, 0.002], "num_seeds": 2, "num_training_iterations": 2,
               "num_rollouts_per_eval": 4, "progress": False}
    batched, looped = learning_rate_sweep(**options), learning_rate_sweep(**options, batched=False)
    np.testing.assert_array_equal(batched.rewards, looped.rewards)
    assert len(np.unique(batched.rewards)) > 3


def eval_unseeded_until_enough(params, num_rollouts=20, seed=0):
    """Correct, unseeded, and it stops early once it has seen enough reward: its recording pass
    (placeholder rewards) asks for more starts than its real pass uses."""
    policy = CartPoleLinearPolicy(params)
    rewards = []
    while len(rewards) < num_rollouts:
        rewards.append(run_policy(policy))
        if sum(rewards) >= 1000:
            break
    return float(np.mean(rewards))


def test_unseeded_starts_a_call_did_not_use_go_back_to_the_runs_env(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_unseeded_until_enough)
    kit = run_training(4, 5, 0.002, seed=3, progress=False)
    looped = run_training(4, 5, 0.002, seed=3, batched=False, progress=False)
    assert any(reward >= 200 for reward in looped.rewards)  # the early stop is taken
    np.testing.assert_array_equal(kit.rewards, looped.rewards)
    np.testing.assert_array_equal(kit.params_history, looped.params_history)


@pytest.mark.parametrize("in_blocks", [False, True], ids=["one reset each", "in blocks"])
def test_each_unseeded_start_is_drawn_from_the_runs_env_once(monkeypatch, in_blocks):
    from gymnasium.envs.classic_control.cartpole import CartPoleEnv

    from hwlib.machinery import replay as _replay

    resets, reset = [], CartPoleEnv.reset
    monkeypatch.setattr(CartPoleEnv, "reset", lambda self, *a, **k: resets.append(1) or reset(self, *a, **k))
    monkeypatch.setattr(_replay, "_BLOCKS", [in_blocks])
    monkeypatch.setattr(policy_search, "eval_params", eval_unseeded)
    rewards = run_training(3, 5, 0.001, seed=3, progress=False).rewards
    # One reset per episode (recording and real pass share them); in blocks, resets only for the
    # calls recorded before the run is foreseen, the rest drawn in blocks. Either way the episodes
    # of the plain loop, which a start drawn twice would shift.
    episodes = (1 + 9 * 3) * 5
    assert len(resets) < episodes / 2 if in_blocks else len(resets) == episodes
    monkeypatch.setattr(_replay, "_BLOCKS", [True])
    np.testing.assert_array_equal(rewards, run_training(3, 5, 0.001, seed=3, batched=False, progress=False).rewards)


def test_unseeded_starts_are_drawn_one_reset_at_a_time_if_gymnasium_draws_them_otherwise(monkeypatch):
    from gymnasium.envs.classic_control.cartpole import CartPoleEnv

    from hwlib.machinery import replay as _replay

    assert _replay._resets_draw_in_blocks()  # this gymnasium: k resets draw one block of k x 4 numbers
    original_reset = CartPoleEnv.reset

    def narrower(self, *, seed=None, options=None):  # a gymnasium whose starts lie in (-0.04, 0.04)
        return original_reset(self, seed=seed, options={"low": -0.04, "high": 0.04})

    monkeypatch.setattr(CartPoleEnv, "reset", narrower)
    monkeypatch.setattr(_replay, "_BLOCKS", [])
    assert not _replay._resets_draw_in_blocks()
    monkeypatch.setattr(policy_search, "eval_params", eval_unseeded)
    batched = run_training(3, 5, 0.001, seed=2, progress=False).rewards
    np.testing.assert_array_equal(batched, run_training(3, 5, 0.001, seed=2, batched=False, progress=False).rewards)


# --- eval_params with an environment of its own (issue 25.1) -------------------------------------
# The natural solutions of 1.3.1 that play their episodes in their own gym.make("CartPole-v1"):
# reset(seed=seed + k) each episode, one env seeded at its first reset, or one make_env() passed to
# run_policy. In a kit run that environment is the kit's (replay.KitEnv): the episodes are played in
# the batches, and the numbers are those of the same code on gymnasium's own environment.

OWN_ENVIRONMENT = ["1.3.1_own_env_loop.py", "1.3.1_own_env_seeded_once.py", "1.3.1_one_env_reused.py"]


def natural_eval_params(name):
    """``eval_params`` with ``tests/grader/natural_solutions/<name>`` as its TODO block, its names looked up in
    hwlib/policy_search.py as the student's file looks them up."""
    import textwrap
    import types
    from pathlib import Path

    block = (Path(__file__).resolve().parents[1] / "grader" / "natural_solutions" / name).read_text()
    source = ("def eval_params(params, num_rollouts=20, seed=0):\n    policy = CartPoleLinearPolicy(params)\n"
              "    mean_reward = 0.0\n" + textwrap.indent(block, "    ") + "\n    return float(mean_reward)\n")
    defined = {}
    exec(compile(source, name, "exec"), vars(policy_search), defined)
    return types.FunctionType(defined["eval_params"].__code__, vars(policy_search), "eval_params",
                              defined["eval_params"].__defaults__)


@pytest.mark.parametrize("name", OWN_ENVIRONMENT)
def test_an_eval_params_with_its_own_environment_is_played_in_the_batches_with_the_plain_numbers(monkeypatch, name):
    import gymnasium

    make = gymnasium.make
    monkeypatch.setattr(policy_search, "eval_params", natural_eval_params(name))
    session, replaying = session_replaying()
    with replaying:
        [run] = session.run([lambda: policy_search.train_cartpole_policy(4, 5, 0.002, seed=3)])
    plain = policy_search.train_cartpole_policy(4, 5, 0.002, seed=3)  # outside a kit run: gymnasium's environment
    np.testing.assert_array_equal(run.rewards, plain.rewards)
    np.testing.assert_array_equal(run.params_history, plain.params_history)
    assert len(np.unique(run.rewards)) > 2  # real curves
    assert session.not_replayed is None and session.episodes_played == (1 + 9 * 4) * 5  # every episode in the batches
    assert gymnasium.make is make


@pytest.mark.parametrize("name", OWN_ENVIRONMENT)
def test_a_sweep_with_its_own_environment_equals_the_plain_loop(monkeypatch, name):
    monkeypatch.setattr(policy_search, "eval_params", natural_eval_params(name))
    options = {"learning_rates": [0.0005, 0.002], "num_seeds": 2, "first_seed": 3, "num_training_iterations": 3,
               "num_rollouts_per_eval": 5, "progress": False}
    batched = learning_rate_sweep(**options)
    np.testing.assert_array_equal(batched.rewards, learning_rate_sweep(**options, batched=False).rewards)
    assert len(np.unique(batched.rewards)) > 3


def eval_counting_steps(params, num_rollouts=20, seed=0):
    """Counts steps rather than adding up rewards: in gymnasium's CartPole (+1 a step) the same number."""
    import gymnasium as gym

    policy, env, steps = CartPoleLinearPolicy(params), gym.make("CartPole-v1"), 0
    for k in range(num_rollouts):
        obs, _ = env.reset(seed=seed + k)
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(policy(obs))
            steps += 1
            done = terminated or truncated
    return steps / num_rollouts


def eval_capped(params, num_rollouts=20, seed=0):
    """Wrong (episodes end after 60 steps), and a plain loop: its numbers are what the kit must give."""
    import gymnasium as gym

    policy, env, total = CartPoleLinearPolicy(params), gym.make("CartPole-v1"), 0.0
    for k in range(num_rollouts):
        obs, _ = env.reset(seed=seed + k)
        for _ in range(60):
            obs, reward, terminated, truncated, _ = env.step(policy(obs))
            total += reward
            if terminated or truncated:
                break
    return total / num_rollouts


def eval_always_left(params, num_rollouts=20, seed=0):
    """Wrong (it never asks the policy), and a plain loop."""
    import gymnasium as gym

    env, total = gym.make("CartPole-v1"), 0.0
    for k in range(num_rollouts):
        env.reset(seed=seed + k)
        done = False
        while not done:
            _, reward, terminated, truncated, _ = env.step(0)
            total += reward
            done = terminated or truncated
    return total / num_rollouts


KEPT = {}


def eval_env_kept_between_calls(params, num_rollouts=20, seed=0):
    """Correct: one environment made at the first call and kept for the next ones."""
    import gymnasium as gym

    if "env" not in KEPT:
        KEPT["env"] = gym.make("CartPole-v1")
    env = KEPT["env"]
    policy, total = CartPoleLinearPolicy(params), 0.0
    for k in range(num_rollouts):
        obs, _ = env.reset(seed=seed + k)
        done = False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(policy(obs))
            total += reward
            done = terminated or truncated
    return total / num_rollouts


@pytest.mark.parametrize("student", [eval_counting_steps, eval_capped, eval_always_left, eval_env_kept_between_calls])
def test_own_environment_code_the_kit_cannot_replay_gets_the_plain_loops_numbers(monkeypatch, student):
    monkeypatch.setattr(policy_search, "eval_params", student)
    KEPT.clear()
    session, replaying = session_replaying()
    with replaying:
        [run] = session.run([lambda: policy_search.train_cartpole_policy(4, 5, 0.004, seed=3)])
    KEPT.clear()
    plain = policy_search.train_cartpole_policy(4, 5, 0.004, seed=3)
    np.testing.assert_array_equal(run.rewards, plain.rewards)
    np.testing.assert_array_equal(run.params_history, plain.params_history)
    assert session.not_replayed is not None  # the kit noticed, and made no more of its environments
    if student is eval_env_kept_between_calls:  # the first call's environment replays no other call's episodes
        assert "keeps its environment" in session.not_replayed


def test_a_sweep_whose_own_environment_cannot_be_replayed_is_stopped_with_the_reason(monkeypatch):
    monkeypatch.setattr(policy_search, "eval_params", eval_counting_steps)
    with pytest.raises(TooSlow, match=r"This learning-rate sweep would take about") as caught:
        learning_rate_sweep([0.001, 0.002], num_seeds=10, progress=False, max_minutes=0.01)
    assert "environment of its own" in caught.value.second and "count steps" in caught.value.second
    assert "run_policy(policy, seed=seed + k)" in caught.value.second
    assert not run_threads_left()


@pytest.mark.timeout(300)
def test_kernel_interrupt_stops_a_sweep_whose_eval_params_has_its_own_environment(kernel_interrupt, monkeypatch):
    import gymnasium

    make = gymnasium.make
    monkeypatch.setattr(policy_search, "eval_params", natural_eval_params("1.3.1_own_env_seeded_once.py"))
    interrupt_the_sweep(kernel_interrupt, monkeypatch, after_rounds=4)
    assert not run_threads_left()
    assert gymnasium.make is make and policy_search.run_policy is cartpole.run_policy
