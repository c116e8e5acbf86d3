"""The shipped human models reproduce their model cards' test IoU on freshly generated test images."""
import pytest

from cerberus_core import zoo
from cerberus_core.cli import main

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def card_test_split(tmp_path_factory):
    """The human cards' test split (the large preset's, which is the small one's: 208 images); a one-pair training
    split keeps this quick, and the test split does not depend on it."""
    sizes = {zoo.available()[name].data["size"] for name in ("human", "human-silhouette")}
    assert sizes == {"large"}
    data = tmp_path_factory.mktemp("zoo") / "human"
    assert main(["data", "generate", "--dataset", "human", "--size", "large", "--set", "splits.train.pairs=1",
                 "--out", str(data), "--quiet"]) == 0
    return data


def _iou(printed: str) -> float:
    return float(printed.split("images: ")[1].split(";")[0].split()[0])


def test_shipped_human_model_scores_its_card_iou(card_test_split, tmp_path, capsys):
    entry = zoo.available()["human"]
    assert entry.data["dataset"] == "human"
    assert main(["eval", "human", "--data", str(card_test_split), "--out", str(tmp_path / "eval"), "--no-part-quality",
                 "--figure-images", "2", "--viewer-images", "0"]) == 0
    printed = capsys.readouterr().out
    assert _iou(printed) == pytest.approx(entry.results["test_iou"], abs=0.005), printed
    assert float(printed.split("Hard Human: ")[1].split()[0]) == pytest.approx(entry.results["hard_human_iou"], abs=0.005)
    # and reconstructs a test image by name, without training
    image = next((tmp_path / "eval" / "pictures").glob("*_input.png"))
    assert main(["reconstruct", "--model", "human", str(image), "--out", str(tmp_path / "rec")]) == 0
    assert (tmp_path / "rec" / "index.html").is_file() and any((tmp_path / "rec").glob("*.glb"))


def test_shipped_silhouette_model_scores_its_card_iou_on_flat_silhouettes(card_test_split, tmp_path, capsys):
    """Issue 41: `human-silhouette` is scored in the look it learned (flat silhouettes) without being told."""
    entry = zoo.available()["human-silhouette"]
    assert entry.data == {"dataset": "human", "size": "large", "input_look": "flat"}
    assert main(["eval", "human-silhouette", "--data", str(card_test_split), "--out", str(tmp_path / "eval"),
                 "--no-part-quality", "--no-hard", "--no-segments", "--no-allocation", "--no-visibility", "--no-depth",
                 "--figure-images", "1", "--viewer-images", "0"]) == 0
    printed = capsys.readouterr().out
    assert "the test images in the flat input look" in printed
    assert _iou(printed) == pytest.approx(entry.results["test_iou"], abs=0.005), printed
