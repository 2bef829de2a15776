"""stereo_classic.cli.config: the TOML config of run, merged with flags."""

from __future__ import annotations


def test_merge_precedence_and_dump_round_trip(tmp_path):
    from stereo_classic.cli.config import RUN_DEFAULTS, dump_config, load_config, merge_config

    path = tmp_path / "c.toml"
    path.write_text('conf = 0.2\nseed = 3\nclasses = ["car"]\n[matcher]\nnum_disparities = 64\ncensus_window = [7, 5]\n')
    file_cfg = load_config(path)
    merged = merge_config(file_cfg, {"seed": 7, "conf": None}, {"cost": "sad"})
    assert merged["conf"] == 0.2 and merged["seed"] == 7 and merged["classes"] == ["car"]
    assert merged["matcher"] == {"num_disparities": 64, "census_window": (7, 5), "cost": "sad"}
    assert merged["box_shrink"] == RUN_DEFAULTS["box_shrink"][0]
    path.write_text(dump_config(merged))
    again = merge_config(load_config(path), {}, {})
    assert again == merged


