"""Configuration: the store's flush interval (a daemon setting that bounds memory and the log)."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.config import load_config
from twin.errors import ConfigError


def test_the_store_is_flushed_every_minute_unless_configured(tmp_path: Path) -> None:
    assert load_config().store_flush_every_s == 60.0
    path = tmp_path / "c.toml"
    path.write_text("[store]\nflush_every_s = 15\n")
    assert load_config(path).store_flush_every_s == 15.0


@pytest.mark.parametrize("value", ["0", "-5", "7200", "true", '"often"'])
def test_a_bad_flush_interval_is_refused_by_name(tmp_path: Path, value: str) -> None:
    path = tmp_path / "c.toml"
    path.write_text(f"[store]\nflush_every_s = {value}\n")
    with pytest.raises(ConfigError, match=r"'store.flush_every_s' must be seconds from 1 to 3600"):
        load_config(path)
