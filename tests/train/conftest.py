import pytest

from synthetic_demos import write_synthetic_dataset

#: tiny settings: every module trains in about a second on 2 CPU cores
TINY = {
    "vae": {"epochs": "2", "width": "16", "fold_hidden": "16", "input_points": "64", "target_points": "64",
            "emd_points": "16", "num_points": "128", "stride": "2", "progress": "false", "batch_size": "8"},
    "feasibility": {"epochs": "2", "hidden": "16", "num_points": "128", "match_points": "64", "progress": "false", "threads": "1"},
    "cost": {"epochs": "2", "hidden": "16", "num_points": "128", "label_points": "64", "pairs_per_entity": "4",
             "stride": "2", "progress": "false", "threads": "1"},
}


@pytest.fixture(scope="session")
def three_demos(tmp_path_factory):
    """A generated dataset of 3 cut demonstrations, 4 steps each, 400 points."""
    return write_synthetic_dataset(tmp_path_factory.mktemp("demos"), per_skill=3, skills=("cut",), steps=4, num_points=400)


@pytest.fixture(scope="session")
def tiny():
    return TINY
