"""Unknown keys in a TOML table: one ConfigError naming the key and suggesting the nearest allowed one."""

from __future__ import annotations

import difflib

from pounding_sweep.errors import ConfigError


def check_keys(table: dict, allowed, where: str) -> None:
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.6)
            hint = f"; did you mean '{close[0]}'?" if close else f"; allowed: {', '.join(sorted(allowed))}"
            raise ConfigError(f"unknown key '{key}' in {where}{hint}")
