"""The food-cutting data set of problem 2: the course's file, or a synthetic stand-in.

A Franka robot cuts seven kinds of food; each sample is one cut, described by 220 numbers:

| columns   | count        | content                                                           |
|-----------|--------------|-------------------------------------------------------------------|
| 0-159     | 4 x 40       | 4 contact microphones (3 on the board, 1 on the end effector), 40 MFCC values each, one per 0.1 s step; microphone-major: column ``40 * mic + step`` |
| 160-219   | 10 x 6       | end-effector force/torque (fx, fy, fz, tx, ty, tz) at 10 steps; step-major: column ``160 + 6 * step + component`` |

| key in ``data.npz`` | shape      | dtype                 | meaning                          |
|---------------------|------------|-----------------------|----------------------------------|
| ``features``        | (N, 220)   | real numbers          | one cut per row, the layout above |
| ``labels``          | (N,)       | integers 0..6         | the food, index into ``names``   |
| ``names``           | (7,)       | strings               | the foods, in ``FOOD_NAMES`` order |

The course's file has N = 10658. It is not part of the kit: ``load_food_cutting`` reads it from
an explicit path or from ``<kit>/data/data.npz``, and without it falls back to
``make_synthetic_food_cutting``, a deterministic stand-in with the same schema and size. The
result says which source it came from (``FoodCuttingData.source``, ``.banner``).

Loading never unpickles (``allow_pickle=False``): a file that is missing, not an npz, truncated,
lacks a key, holds an object array, has the wrong shapes, non-finite features or labels out of
range is rejected with an error that names the file and the problem.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hwlib.machinery.validation import check_seed

FOOD_NAMES = ("Apple", "Carrot", "Cucumber", "Frozen Lemon", "Celery", "Onion", "Potato")
NUM_CLASSES = len(FOOD_NAMES)
NUM_SAMPLES = 10658
NUM_MICROPHONES = 4
NUM_MFCC_STEPS = 40
NUM_FORCE_STEPS = 10
NUM_FORCE_COMPONENTS = 6
NUM_AUDIO_FEATURES = NUM_MICROPHONES * NUM_MFCC_STEPS
NUM_FEATURES = NUM_AUDIO_FEATURES + NUM_FORCE_STEPS * NUM_FORCE_COMPONENTS
DATA_KEYS = ("features", "labels", "names")

KIT_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_DATA_PATH = KIT_ROOT / "data" / "data.npz"
DEFAULT_AUDIO_DIR = KIT_ROOT / "data" / "audio"

COURSE_FILE = "course file"
SYNTHETIC = "synthetic stand-in"


@dataclass(frozen=True)
class FoodCuttingData:
    """Features (N, 220) float64, labels (N,) int64 in 0..6, the 7 class names, and where they came from.

    Unpacks like a tuple: ``features, labels, names = load_food_cutting()``.
    """

    features: np.ndarray
    labels: np.ndarray
    names: tuple
    source: str  # COURSE_FILE or SYNTHETIC
    path: Path | None = None  # the file read, None for the stand-in

    def __iter__(self):
        return iter((self.features, self.labels, self.names))

    @property
    def is_synthetic(self):
        return self.source == SYNTHETIC

    @property
    def class_counts(self):
        """Number of samples of each class, shape (7,)."""
        return np.bincount(self.labels, minlength=len(self.names))

    @property
    def banner(self):
        """One line saying which data this is, for the top of the notebook."""
        shape = f"{self.features.shape[0]} samples x {self.features.shape[1]} features"
        if self.is_synthetic:
            return (
                f"DATA SOURCE: synthetic stand-in ({shape}); the course's data.npz was not found at "
                f"{_display_path(DEFAULT_DATA_PATH)}. Numbers below are not those of the real data."
            )
        return f"DATA SOURCE: course file {_display_path(self.path)} ({shape})"


def load_food_cutting(path=None, *, fallback_to_synthetic=True, seed=0):
    """The food-cutting data as a ``FoodCuttingData``.

    With ``path``, that file is read and must exist. Without it, ``<kit>/data/data.npz`` is read
    if present; if it is absent, the result is ``make_synthetic_food_cutting(seed)`` (or a
    FileNotFoundError when ``fallback_to_synthetic`` is False). A file that exists but is
    broken is always an error, never silently replaced by the stand-in.
    """
    if path is None:
        if DEFAULT_DATA_PATH.exists() or not fallback_to_synthetic:
            return _read_food_file(DEFAULT_DATA_PATH)
        return make_synthetic_food_cutting(seed)
    if not isinstance(path, (str, Path)):
        raise TypeError(f"path must be a str or pathlib.Path naming a .npz file, got {type(path).__name__}")
    return _read_food_file(Path(path))


def find_audio_examples(audio_dir=None):
    """The example recordings ``<label>_<food>.wav`` as ``{label: path}``; empty if the folder is absent."""
    folder = DEFAULT_AUDIO_DIR if audio_dir is None else Path(audio_dir)
    if not folder.is_dir():
        return {}
    examples = {}
    for label in range(NUM_CLASSES):
        matches = sorted(folder.glob(f"{label}_*.wav"))
        if matches:
            examples[label] = matches[0]
    return examples


# --- reading and checking the course's file -------------------------------------------------


def _read_food_file(path):
    if not path.exists():
        raise FileNotFoundError(
            f"food-cutting data file {path} does not exist (put the course's data.npz there, "
            f"or leave path=None to use the synthetic stand-in)"
        )
    if not path.is_file():
        raise ValueError(f"food-cutting data file {path} is not a regular file")
    arrays = _read_npz_arrays(path)
    features, labels, names = _check_food_arrays(path, arrays)
    return FoodCuttingData(features, labels, names, COURSE_FILE, path)


def _read_npz_arrays(path):
    """The three arrays of the archive, read without unpickling anything."""
    try:
        archive = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as error:
        # numpy reports a file that is neither .npz nor .npy as "pickled data": it is not read.
        raise ValueError(f"{path} is not a readable .npz archive (truncated, corrupt or another format): {error}") from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ValueError(f"{path} is a single .npy array, not an .npz archive with keys {DATA_KEYS}")
    with archive:
        missing = [key for key in DATA_KEYS if key not in archive.files]
        if missing:
            raise ValueError(f"{path} lacks the key(s) {missing}; it holds {sorted(archive.files)}, expected {DATA_KEYS}")
        return {key: _read_member(path, archive, key) for key in DATA_KEYS}


def _read_member(path, archive, key):
    try:
        return archive[key]
    except ValueError as error:
        if "pickle" in str(error).lower():
            raise ValueError(
                f"{path}: '{key}' is an object array, which would need unpickling; refused (allow_pickle=False)"
            ) from None
        raise ValueError(f"{path}: '{key}' cannot be read: {error}") from None
    except (zipfile.BadZipFile, OSError, EOFError) as error:
        raise ValueError(f"{path}: '{key}' cannot be read (truncated or corrupt?): {error}") from None


def _check_food_arrays(path, arrays):
    features, labels, names = arrays["features"], arrays["labels"], arrays["names"]
    if features.dtype.kind not in "iuf" or features.ndim != 2 or features.shape[1] != NUM_FEATURES or len(features) == 0:
        raise ValueError(
            f"{path}: 'features' must be a real-number array of shape (N, {NUM_FEATURES}), "
            f"got dtype {features.dtype} and shape {features.shape}"
        )
    features = features.astype(np.float64)
    num_bad = features.size - np.count_nonzero(np.isfinite(features))
    if num_bad:
        raise ValueError(f"{path}: 'features' holds {num_bad} NaN or infinite entries")
    if labels.ndim != 1 or len(labels) != len(features):
        raise ValueError(f"{path}: 'labels' must have shape ({len(features)},), one per row of features, got {labels.shape}")
    if labels.dtype.kind == "f" and np.all(np.isfinite(labels)) and np.all(labels == np.round(labels)):
        labels = labels.astype(np.int64)
    if labels.dtype.kind not in "iu":
        raise ValueError(f"{path}: 'labels' must hold integer class indices, got dtype {labels.dtype}")
    labels = labels.astype(np.int64)
    out_of_range = np.unique(labels[(labels < 0) | (labels >= NUM_CLASSES)])
    if out_of_range.size:
        raise ValueError(f"{path}: 'labels' must lie in 0..{NUM_CLASSES - 1}, found {out_of_range[:5].tolist()}")
    if names.dtype.kind not in "US" or names.shape != (NUM_CLASSES,):
        raise ValueError(
            f"{path}: 'names' must be {NUM_CLASSES} strings, got dtype {names.dtype} and shape {names.shape}"
        )
    names = tuple(str(name.decode("utf-8", "replace") if isinstance(name, bytes) else name) for name in names.tolist())
    return features, labels, names


def _display_path(path):
    try:
        return str(path.relative_to(KIT_ROOT))
    except ValueError:
        return str(path)


# --- the synthetic stand-in -----------------------------------------------------------------

# Class sizes of the stand-in (they sum to 10658, Apple the largest at 18%).
SYNTHETIC_CLASS_COUNTS = (1918, 1480, 1562, 1290, 1404, 1521, 1483)
# Shape of the stand-in, tuned so that the kit's default training (summed gradient, learning
# rate 0.1, raw features) climbs gradually the way the course reported for the real file.
_LOUDNESS_STD = 12.8  # spread of the class loudness levels, per microphone
_BURST_MEAN, _BURST_STD = 51.0, 12.8  # the knife going through the food
_GAIN_STD = 8.1  # per-cut microphone gain, the same for each of its 40 steps
_MIC_NOISE_STD = 9.0
_FORCE_CLASS_STD = 5.7  # spread of the mean force/torque of the foods
_PRESS_FORCE = 15.0  # the downward push every cut shares (fz)
_FORCE_NOISE_STD = 1.8
_ODD_FRACTION = 0.029  # cuts that sound and feel partly like another food ...
_ODD_BLEND = (0.49, 0.89)  # ... by this much ...
_ODD_NOISE = (4.6, 7.1)  # ... and are this many times noisier
_FEATURE_SCALE = 0.01  # the stand-in's unit: keeps the summed-gradient steps of rate 0.1 stable


def make_synthetic_food_cutting(seed=0):
    """A deterministic stand-in for the course's file: 10658 cuts x 220 features, 7 foods.

    Same schema and column layout as ``data.npz``. Each food has its own loudness and a burst
    of sound when the knife goes through, at its own time and width, on each microphone, and
    its own mean force/torque; every cut adds its own microphone gain, push strength and
    sensor noise. About 3% of the cuts are odd: partly like another food and much noisier,
    which makes the last percent of training slow and costs a couple of points on the test set.
    The features are centred and in arbitrary small units, not those of the real file.
    Returns a ``FoodCuttingData`` with source ``SYNTHETIC``; the same seed gives the same data.
    """
    rng = np.random.default_rng(check_seed(seed, "seed"))
    num_samples = sum(SYNTHETIC_CLASS_COUNTS)
    labels = rng.permutation(np.repeat(np.arange(NUM_CLASSES), SYNTHETIC_CLASS_COUNTS))
    audio_templates = _audio_templates(rng)  # (7, 4, 40)
    force_means = _FORCE_CLASS_STD * rng.normal(size=(NUM_CLASSES, NUM_FORCE_COMPONENTS))
    force_means[:, 2] -= _PRESS_FORCE

    odd = rng.random(num_samples) < _ODD_FRACTION
    noise_scale = np.where(odd, np.exp(rng.uniform(*np.log(_ODD_NOISE), num_samples)), 1.0)
    other_food = (labels + rng.integers(1, NUM_CLASSES, num_samples)) % NUM_CLASSES
    blend = np.where(odd, rng.uniform(*_ODD_BLEND, num_samples), 0.0)

    def mix(templates):  # each cut's template, odd ones pulled towards another food
        weight = blend.reshape((-1,) + (1,) * (templates.ndim - 1))
        return (1.0 - weight) * templates[labels] + weight * templates[other_food]

    audio = mix(audio_templates) + rng.normal(0.0, _GAIN_STD, (num_samples, NUM_MICROPHONES, 1))
    audio += _MIC_NOISE_STD * noise_scale[:, None, None] * rng.normal(size=(num_samples, NUM_MICROPHONES, NUM_MFCC_STEPS))
    press_profile = np.sin(np.linspace(0.0, np.pi, NUM_FORCE_STEPS))[None, :, None]
    push_strength = rng.uniform(0.7, 1.3, (num_samples, 1, 1))
    force = mix(force_means)[:, None, :] * press_profile * push_strength
    force += _FORCE_NOISE_STD * noise_scale[:, None, None] * rng.normal(size=(num_samples, NUM_FORCE_STEPS, NUM_FORCE_COMPONENTS))

    features = np.concatenate([audio.reshape(num_samples, -1), force.reshape(num_samples, -1)], axis=1)
    features = _FEATURE_SCALE * (features - features.mean(axis=0))
    return FoodCuttingData(features, labels.astype(np.int64), FOOD_NAMES, SYNTHETIC)


def _audio_templates(rng):
    """Per food and microphone: a loudness level plus a Gaussian burst over the 40 steps."""
    steps = np.linspace(0.0, 1.0, NUM_MFCC_STEPS)
    level = _LOUDNESS_STD * rng.normal(size=(NUM_CLASSES, NUM_MICROPHONES, 1))
    burst = rng.normal(_BURST_MEAN, _BURST_STD, (NUM_CLASSES, NUM_MICROPHONES, 1))
    burst_time = rng.uniform(0.3, 0.7, (NUM_CLASSES, 1, 1))
    burst_width = rng.uniform(0.1, 0.25, (NUM_CLASSES, 1, 1))
    return level + burst * np.exp(-0.5 * ((steps - burst_time) / burst_width) ** 2)
