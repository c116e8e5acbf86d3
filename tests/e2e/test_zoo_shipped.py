"""The shipped human model reproduces its model card's test IoU on freshly generated test images."""
import pytest

from cerberus_core import zoo
from cerberus_core.cli import main

pytestmark = pytest.mark.slow


def test_shipped_human_model_scores_its_card_iou(tmp_path, capsys):
    entry = zoo.available()["human"]
    data = tmp_path / "human"
    # the card's test split (the small preset's 208 images); a one-pair training split keeps this quick,
    # and the test split does not depend on it
    assert entry.data["dataset"] == "human"
    assert main(["data", "generate", "--dataset", "human", "--size", entry.data["size"], "--set", "splits.train.pairs=1",
                 "--out", str(data), "--quiet"]) == 0
    assert main(["eval", "human", "--data", str(data), "--out", str(tmp_path / "eval"), "--no-part-quality",
                 "--figure-images", "2", "--viewer-images", "0"]) == 0
    printed = capsys.readouterr().out
    iou = float(printed.split("images: ")[1].split(";")[0])
    assert iou == pytest.approx(entry.results["test_iou"], abs=0.005), printed
    assert float(printed.split("Hard Human: ")[1].split()[0]) == pytest.approx(entry.results["hard_human_iou"], abs=0.005)
    # and reconstructs a test image by name, without training
    image = next((tmp_path / "eval" / "pictures").glob("*_input.png"))
    assert main(["reconstruct", "--model", "human", str(image), "--out", str(tmp_path / "rec")]) == 0
    assert (tmp_path / "rec" / "index.html").is_file() and any((tmp_path / "rec").glob("*.glb"))
