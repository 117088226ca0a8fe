"""CartPole's step for many episodes at once, and a helper process that plays batches.

``play(params, starts, constants)`` is the loop of ``episodes.py``'s ``play_batch``: it
needs only numpy, so that the helper process can run it without importing gymnasium.

``HelperProcess`` runs this file as a script (``python hwlib/machinery/physics.py``) beside the kit's
sweep: while it plays the episodes half of the sweep's runs wait for, the kit runs the code of
the other half (``batch.py``), so both cores of a 2-core machine work. Batches cross a
pipe as raw float64 numbers; the helper ignores Ctrl-C (the kit stops it) and ends when its
input closes, so it never outlives the kit's process.

| message              | bytes                                                           |
|----------------------|-----------------------------------------------------------------|
| request (kit → helper) | K (int64), then params (K, 4) and starts (K, 4), float64      |
| reply (helper → kit)   | the K rewards, then the seconds it took, float64              |
| end                  | K = 0, or the pipe closes                                       |
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np

NUM_OBSERVATIONS = 4
CONSTANTS = ("gravity", "masspole", "total_mass", "length", "polemass_length", "force_mag", "tau",
             "theta_threshold_radians", "x_threshold", "max_episode_steps")


def play(params, starts, c):
    """Total reward of one episode of equation (1) per row of ``params`` (float64 (K, 4)) from the
    start state ``starts[k]`` (float64 (K, 4)); ``c`` holds CartPole's ``CONSTANTS``.

    The step is gymnasium's own vectorised CartPole step (``CartPoleVectorEnv.step``: the same
    equations, constants and order of operations), without its per-step checks and auto-reset,
    and in place: the rewards are those of ``env.step``, bit for bit (``tests/test_cartpole.py``
    compares it with gymnasium's vector environment and with the one-by-one loop). An episode
    that has ended is still stepped (its reward is kept) until a quarter of those stepped have
    ended; then the rest go on alone.
    """
    x, x_dot, theta, theta_dot = (np.array(row, dtype=np.float64) for row in starts.T)  # copies, stepped in place
    p0, p1, p2, p3 = (np.ascontiguousarray(params[:, j]) for j in range(NUM_OBSERVATIONS))
    rewards = np.zeros(len(params))
    rows, going, num_going, steps = np.arange(len(params)), np.ones(len(params), dtype=bool), len(params), 0
    while num_going:
        # Equation (1) on what env.step returns (float32), as episodes.batch_actions computes it.
        score = p0 * x.astype(np.float32)
        score += p1 * x_dot.astype(np.float32)
        score += p2 * theta.astype(np.float32)
        score += p3 * theta_dot.astype(np.float32)
        force = (score < 0) * (2.0 * c.force_mag) - c.force_mag  # +force_mag where score < 0, else -force_mag
        costheta, sintheta = np.cos(theta), np.sin(theta)
        temp = np.square(theta_dot)  # temp = (force + polemass_length * theta_dot**2 * sintheta) / total_mass
        temp *= c.polemass_length
        temp *= sintheta
        temp += force
        temp /= c.total_mass
        below = np.square(costheta)  # length * (4/3 - masspole * costheta**2 / total_mass)
        below *= c.masspole
        below /= c.total_mass
        np.subtract(4.0 / 3.0, below, out=below)
        below *= c.length
        thetaacc = c.gravity * sintheta  # (gravity * sintheta - costheta * temp) / below
        thetaacc -= costheta * temp
        thetaacc /= below
        xacc = c.polemass_length * thetaacc  # temp - polemass_length * thetaacc * costheta / total_mass
        xacc *= costheta
        xacc /= c.total_mass
        np.subtract(temp, xacc, out=xacc)
        x += c.tau * x_dot  # Euler: the positions move with the old velocities
        xacc *= c.tau
        x_dot += xacc
        theta += c.tau * theta_dot
        thetaacc *= c.tau
        theta_dot += thetaacc
        steps += 1  # +1 reward for every step, the last one included
        if steps >= c.max_episode_steps:  # truncated
            rewards[rows[going]] = steps
            break
        ended = np.abs(x) > c.x_threshold
        ended |= np.abs(theta) > c.theta_threshold_radians
        ended &= going
        if ended.any():
            rewards[rows[ended]] = steps
            going &= ~ended
            num_going -= int(np.count_nonzero(ended))
            if 4 * num_going < 3 * len(rows):
                rows, x, x_dot, theta, theta_dot = rows[going], x[going], x_dot[going], theta[going], theta_dot[going]
                p0, p1, p2, p3 = p0[going], p1[going], p2[going], p3[going]
                going = np.ones(len(rows), dtype=bool)
    return rewards


# Runs this file as a script without the folders a script normally sees first (its own folder
# holds hwlib's modules, the working folder a student's files): only numpy is imported.
_START = "import runpy, sys; sys.path[:] = [p for p in sys.path if p not in ('', '.')]; runpy.run_path(sys.argv[1], run_name='__main__')"


class HelperFailed(RuntimeError):
    """The helper process could not start, or stopped answering: the kit plays in its own process."""


class HelperProcess:
    """A process that plays batches with ``play`` while the kit does other work: ``submit`` a
    batch, then ``collect`` its rewards (one batch at a time). ``close`` ends it."""

    def __init__(self, constants):
        values = {name: getattr(constants, name) for name in CONSTANTS}
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-c", _START, os.path.abspath(__file__), json.dumps(values)],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, bufsize=0)
        except OSError as error:
            raise HelperFailed(f"could not start {__file__}: {error}") from None
        self.size = None  # the K of the batch submitted and not yet collected

    def submit(self, params, starts):
        header = np.array([len(params)], dtype=np.int64).tobytes()
        try:
            self.process.stdin.write(header + params.tobytes() + starts.tobytes())
        except (OSError, ValueError) as error:
            raise HelperFailed(f"the helper process stopped: {error}") from None
        self.size = len(params)

    def collect(self):
        """The rewards of the batch submitted, and the seconds the helper took to play it."""
        size, self.size = self.size, None
        data = _read_exactly(self.process.stdout, 8 * (size + 1))
        if data is None:
            raise HelperFailed(f"the helper process stopped (exit code {self.process.poll()})")
        numbers = np.frombuffer(data, dtype=np.float64)
        return numbers[:size], float(numbers[size])

    def close(self):
        """End the process: at once if it is playing a batch, else once it has read the end."""
        if self.process.poll() is None:
            if self.size is None:
                try:
                    self.process.stdin.close()
                    self.process.wait(0.5)
                except (OSError, subprocess.TimeoutExpired):
                    pass
            if self.process.poll() is None:
                self.process.kill()
                self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            try:
                stream.close()
            except OSError:
                pass


def _read_exactly(stream, size):
    chunks, left = [], size
    while left:
        chunk = stream.read(left)
        if not chunk:
            return None
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _serve(values):
    """The helper process: answer requests until the input ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Kernel → Interrupt reaches the whole process group
    constants = SimpleNamespace(**values)
    source, sink = sys.stdin.buffer, sys.stdout.buffer
    while True:
        header = _read_exactly(source, 8)
        size = 0 if header is None else int(np.frombuffer(header, dtype=np.int64)[0])
        if size <= 0:
            return
        data = _read_exactly(source, 2 * 8 * NUM_OBSERVATIONS * size)
        if data is None:
            return
        numbers = np.frombuffer(data, dtype=np.float64).reshape(2, size, NUM_OBSERVATIONS)
        started = time.perf_counter()
        rewards = play(numbers[0], numbers[1], constants)
        sink.write(rewards.tobytes() + np.float64(time.perf_counter() - started).tobytes())
        sink.flush()


if __name__ == "__main__":
    _serve(json.loads(sys.argv[-1]))
