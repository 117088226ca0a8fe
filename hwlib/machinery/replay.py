"""Record, then replay: how a kit run learns which episodes a call of your code will ask for.

Part of ``batch.py``'s ``Session``. While a session runs,
``Session.replaying(module, names, ...)`` puts a wrapper in place of each named function of
``module`` (``eval_params`` and ``scalar_finite_diff`` in ``hwlib.policy_search``, where your
training looks them up). In a run, the outermost wrapped call

1. runs once with placeholder rewards (``PLACEHOLDER_REWARD`` for every episode not yet played),
   so that every episode it asks for is written down, whatever seeds it uses; the random state
   (the run's own environment, ``OwnEnv``, and numpy's and ``random``'s global ones while the run
   draws from them) is put back afterwards, so that the second run asks for the same episodes
   (the unseeded starts the first run drew are handed to the second, not drawn again);
2. then runs for real, after those episodes were played in one batch with the other runs'.

Foreseen instead of recorded: once a run's ``eval_params`` has asked for the same seeds every
time it was called with the same other arguments (``num_rollouts``, ``seed``; at least twice,
never otherwise), a call whose seeds are known is not run with placeholders: its episodes are
those seeds with its parameters (for a call without seeds: the next starts of the run's own
environment). That halves the Python time of the usual ways to write it (episode k from
``seed + k``, seeds from ``np.random.default_rng(seed)``, no seeds). If a call then asks for
anything else, its outermost call starts again, recorded, and the run is never foreseen again;
the foreseen episodes it did not ask for are played that once.

Your own environment: ``gym.make("CartPole-v1")`` (or ``make_env()``) in the code of
``eval_params`` gives, in a kit run, a ``KitEnv``. Its ``reset`` starts where gymnasium's would; its
first ``step`` ends the episode with the whole episode's reward, played in the batches for
``CartPoleLinearPolicy(params)``: code that adds up the rewards until ``terminated or truncated``
gets the plain loop's number without stepping to the cap. Checked, not trusted: a call that does
anything else with it (another action than the policy's, a step after the end, a reset never
seeded), fails, or meets an episode longer than any checked so far runs again on gymnasium's own
environment, and that plain pass's number is the call's; where the two differ, the session makes
no more kit environments (and its time limit says why it is slow). A kit environment used after
the pass of ``eval_params`` that made it (kept from one call to the next) turns into gymnasium's
own, seeded where it was.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import inspect
import math
import sys

import gymnasium
import numpy as np

from hwlib.cartpole import ENV_ID, CartPoleLinearPolicy, make_env, run_policy
from hwlib.machinery import episodes

PLACEHOLDER_REWARD = 0.0  # what an episode not yet played gives while a call is being recorded
UNSEEDED = "unseeded"  # a call that asks for its episodes without seeds: (UNSEEDED, how many)
_CONFIRMATIONS = 2  # calls that asked again for known seeds before a run is foreseen


class Cancelled(BaseException):
    """Raised inside a run the kit stopped (Kernel → Interrupt, or another run failed)."""


class GiveUpRecording(BaseException):
    """A recording pass that asks for far too many episodes is given up (the real pass plays them)."""


class Redo(BaseException):
    """A foreseen call asked for an episode that was not foreseen: its outermost call starts again."""


class NotReplayable(BaseException):
    """The code of eval_params used a ``KitEnv`` in a way the kit does not replay: the call runs plainly."""


class RunMemory:
    """What a run has learnt about the seeds its ``eval_params`` asks for."""

    def __init__(self):
        self.asked = None  # the episode keys the call being watched asks for, in order
        self.seeds_of = {}  # the call's other arguments -> (policy class, seeds asked)
        self.confirmations = 0
        self.refuted = False
        self.foresaw = False  # the outermost call running now was foreseen, in part or whole
        self.kit_starts = False  # the call being watched drew start states in a KitEnv (fixed by its arguments)

    def foreseeable(self):
        return not self.refuted and self.confirmations >= _CONFIRMATIONS


_START_BOUND = 0.05  # CartPole's reset draws each of the 4 numbers of its start from U(-0.05, 0.05)
_BLOCKS = []


def _resets_draw_in_blocks():
    """Whether k unseeded resets of CartPole draw what one block of k x 4 draws of U(-0.05, 0.05)
    from its generator gives (and leave the generator in the same state): checked once, on the
    environment itself, so that a gymnasium that draws its starts otherwise is reset one by one."""
    if not _BLOCKS:
        one, block = make_env().unwrapped, make_env().unwrapped
        one.reset(seed=2026)
        block.reset(seed=2026)
        starts = []
        for _ in range(3):
            one.reset()
            starts.append(np.asarray(one.state, dtype=np.float64))
        drawn = block.np_random.uniform(low=-_START_BOUND, high=_START_BOUND, size=(3, 4))
        _BLOCKS.append(np.array_equal(np.array(starts), drawn)
                       and one.np_random.bit_generator.state == block.np_random.bit_generator.state)
        one.close()
        block.close()
    return _BLOCKS[0]


class OwnEnv:
    """A run's own environment, where its unseeded episodes start as in the plain loop: its first
    ``reset`` takes the run's seed, the next ones its own stream. The starts drawn for a call's
    recording pass (or foreseen) are handed to its real pass, which asks for the same ones, so they
    are drawn once; any left over are given back (``rewind``)."""

    def __init__(self, seed):
        self.seed, self.env, self.first = seed, None, True
        self.drawn = None  # while recording: the starts drawn, in order
        self.handed = collections.deque()  # drawn for the real pass of the call running now
        self._handed_from, self._num_handed = None, 0  # the state before the first of them, and how many

    def for_reset(self):
        """The env and the seed for its next ``reset`` (the plain loop plays in it)."""
        if self.env is None:
            self.env = make_env()
        seed, self.first = (self.seed if self.first else None), False
        return self.env, seed

    def next_start(self):
        """The start state (float64 bytes) of the run's next unseeded episode."""
        if self.handed:
            return self.handed.popleft()
        env, seed = self.for_reset()
        raw = env.unwrapped  # its reset draws the start; the wrappers' reset only checks and counts
        raw.reset(seed=seed)
        start = np.asarray(raw.state, dtype=np.float64).tobytes()
        if self.drawn is not None:
            self.drawn.append(start)
        return start

    def start_drawing(self):
        """Note the starts drawn from now on (``hand_over`` gives them to the real pass)."""
        self.drawn, self._handed_from = [], self.state()

    def hand_over(self):
        drawn, self.drawn = self.drawn, None
        self.handed.extend(drawn)
        self._num_handed = len(self.handed)

    def next_starts(self, count):
        """The starts of the run's next ``count`` unseeded episodes: those ``next_start`` would give,
        drawn in one block from the env's generator when that is what its resets draw."""
        if not _resets_draw_in_blocks():
            return [self.next_start() for _ in range(count)]
        starts = []
        while self.handed and len(starts) < count:
            starts.append(self.handed.popleft())
        if len(starts) < count and (self.first or self.env is None):
            starts.append(self.next_start())  # the first reset takes the run's seed
        if len(starts) < count:
            raw = self.env.unwrapped
            block = raw.np_random.uniform(low=-_START_BOUND, high=_START_BOUND, size=(count - len(starts), 4))
            raw.state = block[-1].copy()  # where the last of those resets leaves it
            drawn = [row.tobytes() for row in block]
            if self.drawn is not None:
                self.drawn.extend(drawn)
            starts.extend(drawn)
        return starts

    def draw(self, count, hand_over):
        """The next ``count`` starts; ``hand_over``: for the real pass that follows (not a recording)."""
        if not hand_over:
            return self.next_starts(count)
        self.start_drawing()
        try:
            return self.next_starts(count)
        finally:
            self.hand_over()

    def state(self):
        return self.first, None if self.first or self.env is None else self.env.unwrapped.np_random.bit_generator.state

    def set_state(self, state):
        self.handed.clear()
        self.first, generator_state = state
        if generator_state is not None:
            self.env.unwrapped.np_random.bit_generator.state = generator_state

    def rewind(self):
        """After a call: the starts handed to it and not asked for go back to the env."""
        if self.handed:
            used = self._num_handed - len(self.handed)
            self.set_state(self._handed_from)
            self.next_starts(used)

    def close(self):
        if self.env is not None:
            self.env.close()
            self.env = None


class KitEnv:
    """What ``gym.make("CartPole-v1")`` gives the code of ``eval_params`` (a call with ``params``) in a
    batched kit run: see the module's docstring. The real pass checks it (``Replaying._checked``)."""

    _SPACES = ("action_space", "observation_space", "spec", "metadata", "render_mode", "reward_range")

    def __init__(self, session, run, params):
        self._session, self._run = session, run
        self._policy = policy_of(CartPoleLinearPolicy, params)
        self._start = self._obs = self._seed = self._generator = self._real = None
        self._pass = (run.making, run.recording)  # it replays only in the pass of eval_params that made it
        self._plain = False  # from now on gymnasium's own environment
        run.longest = max(run.longest, 0)

    def _live(self):
        """Whether it replays now; if it is used in another pass (code that keeps its environment
        from one call to the next), it becomes gymnasium's own environment."""
        making, recording = self._pass
        if not self._plain and (making is not self._run.making or recording != self._run.recording):
            self._to_plain("it keeps its environment from one call of eval_params to the next")
        return not self._plain

    def _to_plain(self, reason):
        self._plain = True
        if self._session.not_replayed is None:
            self._session.not_replayed = reason

    def _refuse(self, reason):
        """Used otherwise than the kit replays: this pass runs again plainly (``Replaying._checked``)."""
        self._run.longest = math.inf
        self._to_plain(reason)
        raise NotReplayable(reason)

    def _gymnasium(self):
        """Gymnasium's own environment, seeded where this one was."""
        if self._real is None:
            self._real = make_env()
            if self._seed is not None:
                self._real.reset(seed=self._seed)
                self._real.unwrapped.np_random = self._generator or self._real.unwrapped.np_random
        return self._real

    def _begin(self, seed, options=None):
        """Start an episode where gymnasium's reset(seed=seed) would: the episode's seed, or its start state (bytes)."""
        if options is not None or not (seed is None or (isinstance(seed, int) and seed >= 0)):
            self._refuse("it resets its environment with options or an unusual seed")
        if seed is not None:
            self._seed, self._generator, self._start = seed, None, seed
            state = episodes.start_state(seed)
        else:  # the next draw of the env's own generator, seeded by its last seeded reset
            raw = self._session.drawing_env()
            if self._generator is None:
                if self._seed is None:
                    self._refuse("it resets its environment without ever seeding it")
                raw.reset(seed=self._seed)
                self._generator = raw.np_random
            raw.np_random = self._generator
            raw.reset()
            state = np.asarray(raw.state, dtype=np.float64)
            self._start, self._run.memory.kit_starts = state.tobytes(), True
        self._obs = np.array(state, dtype=np.float32)
        return self._start

    def reset(self, *, seed=None, options=None):
        if not self._live():
            return self._gymnasium().reset(seed=seed, options=options)
        self._begin(seed, options)
        return self._obs.copy(), {}

    def step(self, action):
        if not self._live():
            return self._gymnasium().step(action)
        start, self._start = self._start, None
        if start is None:
            self._refuse("it steps an episode that has ended")
        if not episodes.is_action(action) or action != self._policy(self._obs):
            self._refuse("it plays other actions than those of CartPoleLinearPolicy(params)")
        reward = self._session._route(self._run, self._policy, start)
        self._run.longest = max(self._run.longest, reward)
        limit = episodes.constants().max_episode_steps
        return self._obs.copy(), reward, reward < limit, reward >= limit, {}

    def play(self, policy, seed):
        """``run_policy(policy, seed, env=self)``: the kit's own loop, so no check is needed."""
        if not self._live():
            return run_policy(policy, seed, self)
        return self._session._route(self._run, policy, self._begin(seed))

    def close(self):
        if self._real is not None:
            self._real.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        if name not in KitEnv._SPACES and self._live():
            self._refuse(f"it uses env.{name}")
        return getattr(self._gymnasium(), name)


class Replaying:
    """The record-then-replay part of ``Session``, which defines ``_results``, ``_pending``,
    ``batched``, ``cancelled``, ``on_round``, ``_threaded``, ``_stopped_by``, ``_current_run`` and
    ``_routed``; a run has ``recording``, ``recorded``, ``replaying``, ``evaluations``, ``memory``
    and its random state."""

    @contextlib.contextmanager
    def replaying(self, module, names, counted=None, params_argument="params"):
        """While the session runs, ``module.run_policy`` plays its episodes through the session
        (``Session._routed``), and ``module.<name>`` (for each of ``names``) is recorded, then
        replayed, in the session's runs (batched only). Calls of ``counted`` (one of the names)
        advance the progress and may be foreseen: its argument ``params_argument`` holds the
        policy's parameters, its other arguments decide the seeds. Afterwards the module holds
        its own functions again."""
        originals = {name: getattr(module, name) for name in (*names, "run_policy")}
        for name, function in originals.items():
            if name == "run_policy":
                setattr(module, name, self._routed(function))
                continue
            signature = inspect.signature(function) if name == counted else None
            setattr(module, name, self._replayed(function, signature, params_argument))
        make = gymnasium.make
        if self.batched:
            gymnasium.make = self._making(make)
        try:
            yield
        finally:
            gymnasium.make = make
            for name, function in originals.items():
                setattr(module, name, function)
            if self._drawing is not None:
                self._drawing.close()
                self._drawing = None

    def _making(self, make):
        """What stands in for ``gymnasium.make`` while the session runs: a ``KitEnv`` for
        ``make("CartPole-v1")`` called by the code of the counted function (directly or through
        ``make_env()``) in one of the session's runs; gymnasium's own environment anywhere else."""

        @functools.wraps(make)
        def making(*args, **kwargs):
            run = self._current_run()
            if (run is not None and run.session is self and run.making is not None and self.not_replayed is None
                    and args == (ENV_ID,) and kwargs in ({}, {"render_mode": None})):
                frame = sys._getframe(1)
                if frame.f_code is make_env.__code__:
                    frame = frame.f_back
                if frame.f_code is run.making[0]:
                    return KitEnv(self, run, run.making[1])
            return make(*args, **kwargs)

        return making

    def drawing_env(self):
        """The raw CartPole in which the ``KitEnv``s draw their unseeded starts (each with its own generator)."""
        if self._drawing is None:
            self._drawing = make_env()
        return self._drawing.unwrapped

    def _replayed(self, function, signature, params_argument):
        counted = signature is not None

        @functools.wraps(function)
        def replayed(*args, **kwargs):
            run = self._current_run()
            if run is None or run.session is not self:
                return function(*args, **kwargs)
            call = _call_key(signature, params_argument, args, kwargs) if counted and self.batched else None
            code = getattr(function, "__code__", None)  # the code that may make a KitEnv, and its params
            making, run.making = run.making, None if call is None or call[1] is None or code is None else (code, call[1])
            try:
                return self._replay_call(run, call, function, args, kwargs, counted)
            finally:
                run.making = making

        return replayed

    def _replay_call(self, run, call, function, args, kwargs, counted):
        if run.recording:  # inside an outer call's recording pass
            if call is not None and self._foresee(run, call, run.recorded):
                return PLACEHOLDER_REWARD
            return self._watched(run, call, function, args, kwargs)
        if self.cancelled:
            raise Cancelled()
        if run.replaying or not self.batched:  # an outer call's recording covered this one
            return self._real_pass(run, function, args, kwargs, call, counted)
        state, evaluations = run.random_state(), run.evaluations
        try:
            if not (call is not None and self._foresee(run, call, self._pending)):
                self._record(run, function, args, kwargs, state)
            return self._real_pass(run, function, args, kwargs, call, counted)
        except Redo:
            run.set_random_state(state)
            run.evaluations, run.memory.refuted, run.memory.foresaw = evaluations, True, False
            self._record(run, function, args, kwargs, state)
            return self._real_pass(run, function, args, kwargs, call, counted)
        finally:
            run.memory.foresaw = False
            run.own.rewind()

    def _record(self, run, function, args, kwargs, state):
        """Run ``function`` once with placeholder rewards; what it asked for is played in the next round."""
        run.recording, run.recorded = True, {}
        run.own.start_drawing()
        try:
            function(*args, **kwargs)
        except (Cancelled, KeyboardInterrupt):
            raise
        except BaseException:  # noqa: BLE001 - the real pass meets it again, or not
            pass
        finally:
            run.recording = False
            if run.own.drawn:  # the real pass asks for the same starts: it is handed these, not drawn again
                after = run.own.state()
                run.set_random_state(state)
                run.own.set_state(after)
                run.own.hand_over()
            else:
                run.own.drawn = None
                run.set_random_state(state)
        for key, request in run.recorded.items():
            if key not in self._results:
                self._pending.setdefault(key, request)
        run.recorded = {}

    def _real_pass(self, run, function, args, kwargs, call, counted):
        run.replaying += 1
        try:
            value = (self._watched if run.making is None else self._checked)(run, call, function, args, kwargs)
        finally:
            run.replaying -= 1
        if counted:
            run.evaluations += 1
            if not self._threaded and self.on_round is not None:
                try:
                    self.on_round(self)
                except Exception as error:  # raised by run(), outside the code of the run
                    self._stopped_by = error
                    raise Cancelled() from None
        return value

    def _checked(self, run, call, function, args, kwargs):
        """A real pass whose code may play in ``KitEnv``s. If it did and refused, failed, or met an
        episode longer than any checked so far, it runs again plainly (from the same random state),
        and that is its value; if the two differ, the session makes no more ``KitEnv``s."""
        state, handed = run.random_state(), list(run.own.handed)
        run.longest = -1
        try:
            value = self._watched(run, call, function, args, kwargs)
            if run.longest <= self.checked_up_to:
                return value
        except (Exception, NotReplayable):
            if run.longest < 0:  # no KitEnv: its own error
                raise
            value = NotReplayable
        run.set_random_state(state)
        run.own.handed.extend(handed)
        making, run.making = run.making, None
        try:
            plain = function(*args, **kwargs)
        finally:
            run.making = making
        if run.longest < math.inf and np.array_equal(value, plain):
            self.checked_up_to = max(self.checked_up_to, run.longest)
        elif self.not_replayed is None:
            self.not_replayed = "its number changes when the kit plays each episode at once: does it count steps?"
        return plain

    def _watched(self, run, call, function, args, kwargs):
        """Call ``function``; for a foreseeable call, note which episodes it asked for."""
        if call is None:
            return function(*args, **kwargs)
        memory, outer = run.memory, run.memory.asked
        memory.asked, memory.kit_starts = [], False
        try:
            value = function(*args, **kwargs)
            _learn(memory, call, memory.asked)
            return value
        finally:
            memory.asked = outer

    def _foresee(self, run, call, into):
        """If the run is foreseeable and the seeds of ``call`` are known, write its episodes into
        ``into`` (the recording, or the next round) and return True."""
        arguments, params = call
        known = run.memory.seeds_of.get(arguments)
        if known is None or params is None or not run.memory.foreseeable():
            return False
        policy_class, seeds = known
        if seeds[0] == UNSEEDED:  # the next starts of the run's own env: drawn for real while recording
            seeds = run.own.draw(seeds[1], hand_over=into is not run.recorded)
        data = params.tobytes()
        for seed in seeds:
            key = (policy_class, data, seed)
            if key not in self._results:
                into.setdefault(key, (None, params))  # the policy is made from the key if it must play step by step
        run.memory.foresaw = True
        return True


def _learn(memory, call, asked):
    """What a call asked for confirms, or refutes, that the run's seeds depend only on the call's
    other arguments."""
    arguments, params = call
    if not asked:
        return
    data = None if params is None else params.tobytes()
    if any(key[1] != data or key[0] != asked[0][0] for key in asked):
        memory.refuted = True  # it played other parameters than its own, or several policy classes
        return
    unseeded = {isinstance(key[2], bytes) for key in asked}  # a start state, not a seed: see batch.Session._route
    if len(unseeded) > 1 and not memory.kit_starts:
        memory.refuted = True  # seeded and unseeded episodes in one call
        return
    # The starts a KitEnv drew follow from its seeds, like seeds; the run's own env draws new ones every call.
    seeds = (UNSEEDED, len(asked)) if True in unseeded and not memory.kit_starts else tuple(key[2] for key in asked)
    known = memory.seeds_of.get(arguments)
    if known is not None:
        if known == (asked[0][0], seeds):
            memory.confirmations += 1
        else:
            memory.refuted = True
    memory.seeds_of[arguments] = (asked[0][0], seeds)


def _call_key(signature, params_argument, args, kwargs):
    """((the other arguments), params as float64 (4,) or None) of one call; None if the other arguments
    cannot be compared (not hashable) or the call does not bind."""
    try:
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        arguments = tuple((name, value) for name, value in bound.arguments.items() if name != params_argument)
        hash(arguments)
        params = np.asarray(bound.arguments[params_argument], dtype=np.float64).reshape(-1)
    except (TypeError, ValueError, KeyError):
        return None
    return arguments, (params if params.shape == (4,) and np.isfinite(params).all() else None)


# An episode's key names its policy's class by a number: a key then holds only numbers and bytes,
# which Python's garbage collector stops tracking, so the hundreds of thousands of keys a sweep
# keeps do not slow every collection.
CLASSES = [None]  # number -> policy class (numbers from 1)
CLASS_CODES = {}  # policy class -> number


def class_code(policy_class):
    code = CLASS_CODES.get(policy_class)
    if code is None:
        code = CLASS_CODES[policy_class] = len(CLASSES)
        CLASSES.append(policy_class)
    return code


def policy_of(policy_class, params):
    """A policy of ``policy_class`` with the foreseen ``params`` (float64 (4,), finite: read from a
    call of eval_params, whose CartPoleLinearPolicy(params) checks them), not checked again when
    the class keeps the kit's ``__init__``."""
    if policy_class.__init__ is not CartPoleLinearPolicy.__init__:
        return policy_class(params.copy())
    policy = object.__new__(policy_class)
    policy.params = params.copy()
    return policy
