"""Settings of the bench service and CLI: one pydantic-settings class, passed in.

Every field reads ``CALBENCH_<NAME>`` from the environment (``CALBENCH_DATABASE_URL``,
``CALBENCH_TABLE_URL``...). Nothing reads the environment at import time; build
``Settings()`` in the composition root and hand it down.
"""

from __future__ import annotations

import socket
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

_PLACEHOLDER_WORDS = frozenset(
    {
        "n/a", "na", "none", "null", "unknown", "tbd", "tba", "todo", "fixme", "xxx", "changeme",
        "change me", "placeholder", "example", "test", "default", "lorem ipsum", "not set",
        "not configured", "not stated", "unset", "to be set", "to be configured", "set me",
    }
)  # fmt: skip
MIN_LINK_KEY_CHARS = 32
"""Shortest link-signing key (characters)."""
_PLACEHOLDER_PHRASES = ("not configured", "not set", "to be set", "placeholder", "change me", "changeme")


def placeholder_reason(value: str) -> str | None:
    """Why ``value`` is not a real entry of a certificate's identity, or ``None`` when it is one:
    empty or blank; a stand-in (``not configured``, ``address not configured``, ``TBD``,
    ``n/a``, ``changeme``, ``<your lab>``, ...); no letter or digit at all (``-``, ``...``)."""
    text = " ".join(value.split()).lower()
    if not text:
        return "it is empty"
    if (
        text.strip(".!") in _PLACEHOLDER_WORDS
        or any(p in text for p in _PLACEHOLDER_PHRASES)
        or (text.startswith("<") and text.endswith(">"))
        or (text.startswith("${") and text.endswith("}"))
        or not any(c.isalnum() for c in text)
    ):
        return f"{value.strip()!r} is a placeholder"
    return None


class Settings(BaseSettings):
    """Where the bench's devices, data and database are.

    :param database_url: SQLAlchemy URL; empty: ``sqlite:///<data_dir>/calbench.db``.
    :param data_dir: recordings go to ``<data_dir>/recordings``.
    :param table_url: ``sim://?speed=..&rate=..&seed=..`` or a real table URL.
    :param daq_url: ``modbus-tcp://host:port`` (``None`` with a simulated table).
    :param bench_file: the bench's configuration (``calbench-bench/1``, TOML or JSON: table
        axes, mount, lever arm, local g with source and uncertainty, DAQ channels, URLs);
        ``None``: the simulated bench's (``bench/data/benches/sim.toml``), and a real table
        URL is refused.
    :param bench_name: this bench's name in the shared database.
    :param device_lock_dir: the machine-wide directory of the locks on the bench file's real
        devices (``station.execution.device_lock``); ``None``: ``<temp dir>/calbench-device-locks``.
    :param tokens: API tokens (the service's concern).
    :param sim_speed: simulated seconds per wall second for ``--sim``.
    :param sim_sample_rate_hz: DAQ rate of the simulated bench (Hz).
    :param temp_band_c: allowed sensor temperature band (°C) or ``None``.
    :param link_key: the key that signs the service's short-lived links (``POST /api/links``),
        one per deployment, at least 32 characters, so that a link made by one API process
        opens on every other (``calbench serve --workers N``, several hosts on one database);
        empty: ``calbench serve`` draws one at start and hands it to its workers (links then
        die when it restarts), an app built otherwise draws its own.
    :param public_read: reads need no token (a lab that shows the dashboard on a wall screen).
    :param sim: the service drives a simulated bench (``calbench serve --sim``).
    :param agent: ``embedded``: the service runs the bench agent in a thread of its own process
        (one process does everything); ``external``: the agent is another process
        (``calbench agent``) and the service never touches the bench's devices.
    :param sim_process: the simulated bench runs in its own process (like hardware, unaffected
        by how busy the bench's process is); ``False``: threads of the process that drives it.
    :param sim_seed: seed of the simulated bench's noise; each unit's own errors come from its serial.
    :param run_dwell_s: static dwell of runs started over REST (s); ``None``: a noise window decides.
    :param drift_time: local time of the nightly drift check, ``HH:MM``; empty: no scheduler.
    :param drift_procedure: the short check procedure.
    :param drift_dwell_s: its static dwell per pose (s).
    :param drift_k: coverage factor of the drift test |Δ| > k·sqrt(u_ref² + u_check² + u_rep²)
        per coefficient (u_ref: the certificate's standard uncertainty without the contributions
        common to both runs on the same bench, u_rep: the bias repeatability below, bias terms
        only; see
        station/drift/); with 12 coefficients k = 3 flags an unchanged unit with probability
        about 3 % (k = 2: about 43 %).
    :param drift_bias_repeatability_m_s2: standard deviation of a unit's bias change between two
        runs when nothing changed (its bias instability: the run's mean of the slow wander), m/s²;
        added to the drift test's bias limits (default ≈ √2·0.9·40 µg: two runs of a unit whose
        bias wanders by 40 µg with a 200 s correlation time).
    :param limits_file: JSON file of unit-model limits (``calbench-unit-limits/1``); ``None``:
        the one shipped with calbench (``bench/data/unit_limits.json``).
    :param limits_model: model whose limits judge a run when the unit's registration names
        none; empty: no limits, a completed fit gets no verdict. A unit registered as a model the
        limits file lacks is judged by no limits (its certificate makes no statement of conformity).
    :param upload_workers: worker processes that fit and diagnose uploaded recordings
        (``POST /api/recordings``); 0: a thread of the server (never the event loop).
    :param lab_name, lab_address, lab_location: certificate header (ISO/IEC 17025 7.8.2.1 b, c:
        the laboratory and the place of calibration); a real (non-simulated) bench issues no
        certificate while one is empty or a placeholder (:func:`placeholder_reason`).
    :param authorized_by: who authorises certificates (7.8.2.1 o); required as the lab identity is.
    :param reference_equipment: the bench's reference standards and their calibration status,
        ``CALBENCH_REFERENCE_EQUIPMENT="rotary table T-3 s/n 42, cal. PTB-1234, due 2027-03;
        DAQ M-16 s/n 7, cal. DAkkS-55, due 2026-12"`` (``;``-separated, one item each).
    :param ambient_conditions: the laboratory's ambient conditions during calibration, e.g.
        ``"(23 ± 2) °C, 30 % to 60 % rh"`` (7.8.4.1 b); empty: "not stated".
    :param customer_name, customer_address: the customer of units registered without one
        (7.8.2.1 e; an in-house laboratory's own department); empty: "not stated".
    """

    model_config = SettingsConfigDict(env_prefix="CALBENCH_", extra="ignore")

    database_url: str = ""
    data_dir: Path = Path("data")
    table_url: str = "sim://"
    daq_url: str | None = None
    bench_file: Path | None = None
    bench_name: str = Field(default_factory=socket.gethostname)
    device_lock_dir: Path | None = None
    tokens: Annotated[list[str], NoDecode] = Field(default_factory=list)
    link_key: str = Field("", repr=False)
    sim_speed: float = 1.0
    sim_sample_rate_hz: float = 1000.0
    temp_band_c: tuple[float, float] | None = None
    public_read: bool = False
    sim: bool = False
    sim_seed: int = 0
    sim_process: bool = True
    agent: Literal["embedded", "external"] = "embedded"
    run_dwell_s: float | None = None
    drift_time: str = "02:00"
    drift_procedure: str = "static-12"
    drift_dwell_s: float = 20.0
    drift_k: float = 3.0
    drift_bias_repeatability_m_s2: float = Field(5e-4, ge=0, description="bias run-to-run, m/s2")
    limits_file: Path | None = None
    limits_model: str = "ADXL325"
    upload_workers: int = Field(1, ge=0, le=32)
    lab_name: str = ""
    lab_address: str = ""
    lab_location: str = ""
    authorized_by: str = ""
    reference_equipment: Annotated[list[str], NoDecode] = Field(default_factory=list)
    ambient_conditions: str = ""
    customer_name: str = ""
    customer_address: str = ""
    # Type B standard uncertainties of the certificate's uncertainty budget (bench.uncertainty.budget);
    # each is one standard uncertainty (k = 1), normal, with infinite degrees of freedom.
    table_angle_u_deg: float = Field(0.001, ge=0, description="each table axis's angle (encoder), deg")
    base_tilt_u_rad: float = Field(1e-5, ge=0, description="base levelling, each horizontal axis, rad")
    g_local_u_m_s2: float = Field(1e-5, ge=0, description="the local gravity value, m/s2")
    daq_gain_u_rel: float = Field(1e-5, ge=0, description="each DAQ channel's gain, relative")
    daq_offset_u: float = Field(1e-5, ge=0, description="each DAQ channel's offset, channel units (V)")
    temp_coeff_bias_u_m_s2_per_k: float = Field(5e-4, ge=0, description="bias tempco, m/s2 per K")
    temp_coeff_scale_u_rel_per_k: float = Field(3e-5, ge=0, description="scale tempco, per K")
    # The unit's slow bias wander (Gauss-Markov): a moving fit's bias U then covers the unit's
    # long-run bias (bench.uncertainty.dynamic); 0: not stated, the fit's own sigma is used.
    bias_wander_m_s2: float = Field(3.9e-4, ge=0, description="unit's bias wander level, m/s2 (40 ug)")
    bias_wander_corr_time_s: float = Field(200.0, gt=0, description="its correlation time, s")

    @field_validator("tokens", mode="before")
    @classmethod
    def _split_tokens(cls, value: object) -> object:
        """``CALBENCH_TOKENS=operator:SECRET,viewer:SECRET`` (comma-separated ``role:secret``)."""
        if isinstance(value, str):
            return [part.strip() for part in value.split(",") if part.strip()]
        return value

    @field_validator("link_key")
    @classmethod
    def _check_link_key(cls, value: str) -> str:
        """Empty, or a secret of at least :data:`MIN_LINK_KEY_CHARS` characters."""
        if value and len(value) < MIN_LINK_KEY_CHARS:
            raise ValueError(
                f"CALBENCH_LINK_KEY has {len(value)} characters; expected at least {MIN_LINK_KEY_CHARS}"
            )
        return value

    @field_validator("reference_equipment", mode="before")
    @classmethod
    def _split_equipment(cls, value: object) -> object:
        """``;``-separated items, blanks dropped."""
        if isinstance(value, str):
            return [part.strip() for part in value.split(";") if part.strip()]
        return value

    def certificate_gaps(self) -> tuple[list[str], list[str]]:
        """What a certificate of this bench lacks: (``blocking``, ``warnings``), each item naming
        its environment variable. ``blocking`` items (laboratory name and address, the place of
        calibration, the authorising person: empty or a placeholder, :func:`placeholder_reason`)
        stop a real bench from issuing certificates; a simulated one issues them marked not
        traceable, each such item reading "not configured (ENV)"."""
        blocking = [
            f"{what} is not configured ({env}: {why})"
            for what, env, value in (
                ("the laboratory's name", "CALBENCH_LAB_NAME", self.lab_name),
                ("the laboratory's address", "CALBENCH_LAB_ADDRESS", self.lab_address),
                ("the place of calibration", "CALBENCH_LAB_LOCATION", self.lab_location),
                ("the person who authorises certificates", "CALBENCH_AUTHORIZED_BY", self.authorized_by),
            )
            if (why := placeholder_reason(value)) is not None
        ]
        warnings = []
        if not self.reference_equipment:
            warnings.append(
                "the reference equipment and its calibration status are not configured "
                "(CALBENCH_REFERENCE_EQUIPMENT): certificates say 'not stated'"
            )
        if not self.ambient_conditions.strip():
            warnings.append(
                "the ambient conditions are not configured (CALBENCH_AMBIENT_CONDITIONS): "
                "certificates say 'not stated'"
            )
        return blocking, warnings

    @property
    def effective_database_url(self) -> str:
        """``database_url``, or the SQLite file in ``data_dir``."""
        return self.database_url or f"sqlite:///{self.data_dir / 'calbench.db'}"

    @property
    def recordings_dir(self) -> Path:
        """Directory of the run recordings."""
        return self.data_dir / "recordings"
