import pickle
import zipfile

import numpy as np
import pytest

from hwlib import (
    FOOD_NAMES,
    FoodCuttingData,
    find_audio_examples,
    load_food_cutting,
    make_synthetic_food_cutting,
)
from hwlib import food_data


@pytest.fixture(scope="module")
def standin():
    return make_synthetic_food_cutting(0)


def write_food_file(path, features, labels, names=FOOD_NAMES, **extra):
    np.savez(path, features=features, labels=labels, names=np.array(names), **extra)
    return path


@pytest.fixture
def good_file(tmp_path, standin):
    return write_food_file(tmp_path / "data.npz", standin.features[:50], standin.labels[:50])


# --- the stand-in ---------------------------------------------------------------------------


def test_food_names_follow_the_handout():
    assert FOOD_NAMES == ("Apple", "Carrot", "Cucumber", "Frozen Lemon", "Celery", "Onion", "Potato")


def test_standin_has_the_schema_of_the_course_file(standin):
    assert standin.features.shape == (10658, 220)
    assert standin.features.dtype == np.float64
    assert standin.labels.shape == (10658,)
    assert standin.labels.dtype == np.int64
    assert standin.names == FOOD_NAMES
    np.testing.assert_array_equal(standin.class_counts, food_data.SYNTHETIC_CLASS_COUNTS)
    assert np.all(np.isfinite(standin.features))


def test_standin_says_it_is_synthetic(standin):
    assert standin.is_synthetic and standin.source == food_data.SYNTHETIC and standin.path is None
    assert "synthetic stand-in" in standin.banner
    assert "10658 samples x 220 features" in standin.banner


def test_standin_is_deterministic_and_seeded(standin):
    again = make_synthetic_food_cutting(0)
    np.testing.assert_array_equal(again.features, standin.features)
    np.testing.assert_array_equal(again.labels, standin.labels)
    other = make_synthetic_food_cutting(1)
    assert not np.array_equal(other.features, standin.features)


def test_standin_uses_no_global_random_state(standin):
    np.random.seed(123)
    np.testing.assert_array_equal(make_synthetic_food_cutting(0).features[:5], standin.features[:5])


def test_standin_blocks_follow_the_documented_layout(standin):
    # Microphone block: each cut's gain shifts all 40 steps of a microphone together, so
    # steps of the same microphone correlate more than steps of different microphones.
    audio = standin.features[:, :160].reshape(-1, 4, 40)
    same_mic = np.corrcoef(audio[:, 0, 0], audio[:, 0, 39])[0, 1]
    other_mic = np.corrcoef(audio[:, 0, 0], audio[:, 1, 39])[0, 1]
    assert same_mic > other_mic
    # Force block, step-major: the press profile is zero at the first and last step, so
    # those columns hold only sensor noise and vary least.
    force = standin.features[:, 160:].reshape(-1, 10, 6)
    spread = force.std(axis=0)
    assert spread[0].max() < spread[5].min() and spread[9].max() < spread[5].min()


@pytest.mark.parametrize("seed", [-1, 1.5, "0", None])
def test_standin_rejects_bad_seeds(seed):
    with pytest.raises(ValueError, match="seed"):
        make_synthetic_food_cutting(seed)


def test_result_unpacks_into_features_labels_names(standin):
    features, labels, names = standin
    assert features is standin.features and labels is standin.labels and names == FOOD_NAMES


# --- finding and reading the course's file -----------------------------------------------


def test_reads_a_valid_file(good_file, standin):
    data = load_food_cutting(good_file)
    assert isinstance(data, FoodCuttingData)
    assert data.source == food_data.COURSE_FILE and not data.is_synthetic and data.path == good_file
    np.testing.assert_array_equal(data.features, standin.features[:50])
    np.testing.assert_array_equal(data.labels, standin.labels[:50])
    assert data.names == FOOD_NAMES
    assert "course file" in data.banner and "50 samples x 220 features" in data.banner


def test_accepts_a_string_path_bytes_names_and_whole_number_float_labels(tmp_path, standin):
    path = write_food_file(
        tmp_path / "d.npz", standin.features[:7].astype(np.float32), np.arange(7.0), names=[n.encode() for n in FOOD_NAMES]
    )
    data = load_food_cutting(str(path))
    assert data.names == FOOD_NAMES
    assert data.labels.dtype == np.int64 and data.features.dtype == np.float64


def test_default_location_is_used_when_present(monkeypatch, good_file):
    monkeypatch.setattr(food_data, "DEFAULT_DATA_PATH", good_file)
    assert load_food_cutting().source == food_data.COURSE_FILE


def test_falls_back_to_the_standin_only_when_the_default_file_is_absent(monkeypatch, tmp_path, standin):
    monkeypatch.setattr(food_data, "DEFAULT_DATA_PATH", tmp_path / "absent.npz")
    data = load_food_cutting()
    assert data.is_synthetic
    np.testing.assert_array_equal(data.features, standin.features)
    with pytest.raises(FileNotFoundError, match="absent.npz"):
        load_food_cutting(fallback_to_synthetic=False)


def test_a_broken_default_file_is_an_error_not_a_silent_fallback(monkeypatch, tmp_path):
    broken = tmp_path / "data.npz"
    broken.write_text("not an archive")
    monkeypatch.setattr(food_data, "DEFAULT_DATA_PATH", broken)
    with pytest.raises(ValueError, match="data.npz"):
        load_food_cutting()


def test_this_machines_default_data_loads():
    # What the problem 2 notebook relies on, on whichever data this machine has.
    data = load_food_cutting()
    assert data.features.shape[1] == 220 and len(data.names) == 7
    assert set(np.unique(data.labels).tolist()) == set(range(7))
    assert np.all(np.isfinite(data.features))
    if food_data.DEFAULT_DATA_PATH.exists():
        assert data.source == food_data.COURSE_FILE and data.features.shape == (10658, 220)
    else:
        assert data.is_synthetic


# --- bad files -------------------------------------------------------------------------------


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere.npz does not exist"):
        load_food_cutting(tmp_path / "nowhere.npz")


def test_directory_instead_of_file(tmp_path):
    with pytest.raises(ValueError, match="is not a regular file"):
        load_food_cutting(tmp_path)


def test_path_of_the_wrong_type():
    with pytest.raises(TypeError, match="path must be a str or pathlib.Path"):
        load_food_cutting(42)


def test_text_file(tmp_path):
    path = tmp_path / "data.npz"
    path.write_text("features,labels\n1,2\n")
    with pytest.raises(ValueError, match=str(path.name)):
        load_food_cutting(path)


@pytest.mark.parametrize("keep", [0.5, 0.9, 0.1])
def test_truncated_archive(tmp_path, good_file, keep):
    content = good_file.read_bytes()
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(content[: int(len(content) * keep)])
    with pytest.raises(ValueError, match="truncated.npz"):
        load_food_cutting(truncated)


def test_archive_with_a_corrupted_member(tmp_path, good_file):
    content = bytearray(good_file.read_bytes())
    content[200:260] = b"\xff" * 60  # inside the first member's data
    corrupted = tmp_path / "corrupted.npz"
    corrupted.write_bytes(bytes(content))
    with pytest.raises(ValueError, match="corrupted.npz"):
        load_food_cutting(corrupted)


def test_single_npy_array(tmp_path, standin):
    path = tmp_path / "features.npy"
    np.save(path, standin.features[:5])
    with pytest.raises(ValueError, match="single .npy array, not an .npz archive"):
        load_food_cutting(path)


def test_zip_that_is_not_an_npz(tmp_path):
    path = tmp_path / "other.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("readme.txt", "hello")
    with pytest.raises(ValueError, match=r"other.npz lacks the key\(s\) \['features', 'labels', 'names'\]"):
        load_food_cutting(path)


def test_missing_key(tmp_path, standin):
    path = tmp_path / "nonames.npz"
    np.savez(path, features=standin.features[:5], labels=standin.labels[:5])
    with pytest.raises(ValueError, match=r"nonames.npz lacks the key\(s\) \['names'\]"):
        load_food_cutting(path)


class _Payload:
    """Unpickling this would create a marker file: proof that the loader never unpickles."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_object_array_is_refused_without_unpickling(tmp_path, standin):
    marker = tmp_path / "executed"
    path = tmp_path / "pickled.npz"
    labels = np.empty(5, dtype=object)
    labels[:] = [_Payload(marker)] * 5
    np.savez(path, features=standin.features[:5], labels=labels, names=np.array(FOOD_NAMES))
    assert str(marker).encode() in path.read_bytes()  # the payload is in the file ...
    with pytest.raises(ValueError, match=r"pickled.npz: 'labels' is an object array.*refused"):
        load_food_cutting(path)
    assert not marker.exists()  # ... and was never run
    control = tmp_path / "control"
    pickle.loads(pickle.dumps(_Payload(control))).close()  # unpickling it would have run it
    assert control.exists()


@pytest.mark.parametrize(
    "features, labels, names, message",
    [
        (np.ones((5, 219)), np.zeros(5, int), FOOD_NAMES, r"'features' must be a real-number array of shape \(N, 220\)"),
        (np.ones(220), np.zeros(1, int), FOOD_NAMES, r"'features' must be .* got dtype float64 and shape \(220,\)"),
        (np.ones((0, 220)), np.zeros(0, int), FOOD_NAMES, r"'features' must be"),
        (np.full((5, 220), "x"), np.zeros(5, int), FOOD_NAMES, r"'features' must be a real-number array"),
        (np.ones((5, 220)), np.zeros(4, int), FOOD_NAMES, r"'labels' must have shape \(5,\)"),
        (np.ones((5, 220)), np.zeros((5, 1), int), FOOD_NAMES, r"'labels' must have shape \(5,\)"),
        (np.ones((5, 220)), np.full(5, 0.5), FOOD_NAMES, r"'labels' must hold integer class indices"),
        (np.ones((5, 220)), np.array([0, 1, 7, 2, 3]), FOOD_NAMES, r"'labels' must lie in 0\.\.6, found \[7\]"),
        (np.ones((5, 220)), np.array([0, -1, 1, 2, 3]), FOOD_NAMES, r"'labels' must lie in 0\.\.6, found \[-1\]"),
        (np.ones((5, 220)), np.zeros(5, int), FOOD_NAMES[:6], r"'names' must be 7 strings"),
        (np.ones((5, 220)), np.zeros(5, int), list(range(7)), r"'names' must be 7 strings, got dtype int64"),
    ],
)
def test_wrong_shapes_dtypes_and_ranges(tmp_path, features, labels, names, message):
    path = write_food_file(tmp_path / "bad.npz", features, labels, names)
    with pytest.raises(ValueError, match="bad.npz: " + message):
        load_food_cutting(path)


@pytest.mark.parametrize("value, count", [(np.nan, 1), (np.inf, 1), (-np.inf, 1)])
def test_non_finite_features(tmp_path, standin, value, count):
    features = standin.features[:5].copy()
    features[2, 17] = value
    path = write_food_file(tmp_path / "nan.npz", features, standin.labels[:5])
    with pytest.raises(ValueError, match=f"nan.npz: 'features' holds {count} NaN or infinite entries"):
        load_food_cutting(path)


# --- audio examples -------------------------------------------------------------------------


def test_finds_audio_examples_by_label(tmp_path):
    for name in ("0_apple.wav", "4_old_celery.wav", "notes.txt"):
        (tmp_path / name).write_bytes(b"RIFF")
    examples = find_audio_examples(tmp_path)
    assert sorted(examples) == [0, 4]
    assert examples[4].name == "4_old_celery.wav"


def test_no_audio_folder_means_no_examples(tmp_path):
    assert find_audio_examples(tmp_path / "audio") == {}


# --- the figures of problem 2 ----------------------------------------------------------------


def test_training_accuracy_figure_draws_the_curve_and_the_99_percent_line():
    from matplotlib.figure import Figure

    from hwlib.plots.food import plot_training_accuracy

    curve = np.array([0.18, 0.9, 0.97, 0.985, 0.992, 0.996])
    figure = plot_training_accuracy(curve)
    assert isinstance(figure, Figure) and len(figure.axes) == 2
    for ax in figure.axes:
        lines = {line.get_label(): line for line in ax.get_lines()}
        np.testing.assert_array_equal(lines["training accuracy"].get_ydata(), curve)
        np.testing.assert_array_equal(lines["99%"].get_ydata(), [0.99, 0.99])
        assert lines["first above 99%: iteration 4"].get_xdata()[0] == 4
    assert figure.axes[1].get_ylim()[0] == 0.95


def test_training_accuracy_figure_rejects_bad_curves():
    from hwlib.plots.food import plot_training_accuracy

    for bad in ([], [[0.5]], [0.5, 1.5], [0.5, np.nan]):
        with pytest.raises(ValueError, match="accuracies"):
            plot_training_accuracy(bad)


def test_confusion_matrix_figure_labels_foods_and_counts():
    from hwlib.plots.food import plot_confusion_matrix

    counts = np.arange(49).reshape(7, 7)
    ax = plot_confusion_matrix(counts, FOOD_NAMES).axes[0]
    assert [label.get_text() for label in ax.get_xticklabels()] == list(FOOD_NAMES)
    assert [label.get_text() for label in ax.get_yticklabels()] == list(FOOD_NAMES)
    assert sorted(int(text.get_text()) for text in ax.texts) == list(range(49))
    with pytest.raises(ValueError, match=r"counts must be a \(7, 7\) array"):
        plot_confusion_matrix(counts[:6], FOOD_NAMES)
    with pytest.raises(ValueError, match="non-negative integers"):
        plot_confusion_matrix(-counts, FOOD_NAMES)
    with pytest.raises(TypeError, match="class_names"):
        plot_confusion_matrix(counts, "Apple")


def test_per_class_figure_has_one_bar_per_food():
    from hwlib.plots.food import plot_per_class_accuracy

    values = np.array([0.99, 0.97, np.nan, 0.98, 1.0, 0.5, 0.96])
    ax = plot_per_class_accuracy(values, FOOD_NAMES).axes[0]
    heights = [patch.get_height() for patch in ax.patches]
    np.testing.assert_allclose(heights, np.nan_to_num(values))
    assert "no samples" in [text.get_text() for text in ax.texts]
    with pytest.raises(ValueError, match="one value per class name"):
        plot_per_class_accuracy(values[:3], FOOD_NAMES)
    with pytest.raises(ValueError, match=r"fractions in \[0, 1\]"):
        plot_per_class_accuracy(values * 2, FOOD_NAMES)


def test_the_notebooks_play_the_recordings_from_their_files_and_store_no_audio():
    """The players' sound is the file in data/audio/, fetched by the browser when played; nothing of it
    is stored in the notebook (7 embedded recordings made the stored notebook 3.9 MB larger)."""
    import json
    from pathlib import Path

    for path in sorted((Path(__file__).resolve().parents[2] / "notebooks").glob("*.ipynb")):
        for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
            source = "".join(cell["source"])
            if "Audio(" in source:
                assert "embed=False" in source and "url=" in source, f"{path.name}: a player that embeds its recording"
            for output in cell.get("outputs", []):
                html = "".join(output.get("data", {}).get("text/html", ""))
                assert "data:audio" not in html and "base64" not in html, f"{path.name}: an output holds audio data"
                if "<audio" in html:
                    assert '<source src="../data/audio/' in html, html
