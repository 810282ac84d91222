"""Settings of the bench service and CLI: one pydantic-settings class, passed in.

Every field reads ``CALBENCH_<NAME>`` from the environment (``CALBENCH_DATABASE_URL``,
``CALBENCH_TABLE_URL``...). Nothing reads the environment at import time; build
``Settings()`` in the composition root and hand it down.
"""

from __future__ import annotations

import socket
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Where the bench's devices, data and database are.

    :param database_url: SQLAlchemy URL; empty: ``sqlite:///<data_dir>/calbench.db``.
    :param data_dir: recordings go to ``<data_dir>/recordings``.
    :param table_url: ``sim://?speed=..&rate=..&seed=..`` or a real table URL.
    :param daq_url: ``modbus-tcp://host:port`` (``None`` with a simulated table).
    :param bench_name: this bench's name in the shared database.
    :param tokens: API tokens (the service's concern).
    :param sim_speed: simulated seconds per wall second for ``--sim``.
    :param sim_sample_rate_hz: DAQ rate of the simulated bench (Hz).
    :param temp_band_c: allowed sensor temperature band (°C) or ``None``.
    """

    model_config = SettingsConfigDict(env_prefix="CALBENCH_", extra="ignore")

    database_url: str = ""
    data_dir: Path = Path("data")
    table_url: str = "sim://"
    daq_url: str | None = None
    bench_name: str = Field(default_factory=socket.gethostname)
    tokens: list[str] = Field(default_factory=list)
    sim_speed: float = 1.0
    sim_sample_rate_hz: float = 1000.0
    temp_band_c: tuple[float, float] | None = None

    @property
    def effective_database_url(self) -> str:
        """``database_url``, or the SQLite file in ``data_dir``."""
        return self.database_url or f"sqlite:///{self.data_dir / 'calbench.db'}"

    @property
    def recordings_dir(self) -> Path:
        """Directory of the run recordings."""
        return self.data_dir / "recordings"
