-- The run catalog's schema (docs/catalog.md describes every column).
-- Rows are keyed so that indexing a folder again replaces its rows and never adds a copy.

CREATE TABLE IF NOT EXISTS meta (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
);

-- One row per campaign run folder, keyed on the run's id (derived from its manifest).
CREATE TABLE IF NOT EXISTS runs (
    run_id             TEXT PRIMARY KEY,
    dir                TEXT NOT NULL,
    name               TEXT NOT NULL,
    sweep              TEXT,
    status             TEXT NOT NULL,
    reason             TEXT,
    created            TEXT NOT NULL,
    updated            TEXT NOT NULL,
    radbench_version   TEXT NOT NULL,
    git_commit         TEXT,
    simulated          INTEGER NOT NULL,
    bench_file         TEXT,
    waveforms          TEXT NOT NULL,
    algorithms         TEXT NOT NULL,
    scope_idn          TEXT,
    awg_idn            TEXT,
    calibration_sha256 TEXT,
    steps_total        INTEGER NOT NULL,
    steps_done         INTEGER NOT NULL,
    manifest_sha256    TEXT NOT NULL,
    results_sha256     TEXT,
    -- The headline figure (also in run_metrics), here so a listing reads one table.
    max_abs_error_m    REAL
);
-- Newest first, in the order every listing gives: a `--limit` stops after its rows.
CREATE INDEX IF NOT EXISTS runs_newest_first ON runs (created DESC, run_id);
CREATE INDEX IF NOT EXISTS runs_by_name ON runs (name, created);
CREATE INDEX IF NOT EXISTS runs_by_dir ON runs (dir);

-- A run's figures over its steps (the primary algorithm): what `--where` and `trend` read.
CREATE TABLE IF NOT EXISTS run_metrics (
    run_id TEXT NOT NULL REFERENCES runs (run_id) ON DELETE CASCADE,
    name   TEXT NOT NULL,
    value  REAL NOT NULL,
    PRIMARY KEY (run_id, name)
) WITHOUT ROWID;
CREATE INDEX IF NOT EXISTS run_metrics_by_name ON run_metrics (name, value);

-- Every step of a run, with its set-points and its figures per algorithm.
CREATE TABLE IF NOT EXISTS steps (
    run_id        TEXT NOT NULL REFERENCES runs (run_id) ON DELETE CASCADE,
    step          INTEGER NOT NULL,
    algorithm     TEXT NOT NULL,
    status        TEXT NOT NULL,
    dir           TEXT NOT NULL,
    measured_at   TEXT,
    label         TEXT,
    parameter     TEXT,
    value         REAL,
    bandwidth_hz  REAL,
    waveform      TEXT,
    error_m       REAL,
    truth_error_m REAL,
    snr_db        REAL,
    width_3db_cm  REAL,
    sidelobe_db   REAL,
    missed        INTEGER,
    resolved      INTEGER,
    ber           REAL,
    PRIMARY KEY (run_id, step, algorithm)
) WITHOUT ROWID;

-- One row per capture folder (a `summary.json`): `radbench capture`, `radbench process`, or a
-- campaign step (`run_id` and `step` set).
CREATE TABLE IF NOT EXISTS captures (
    dir              TEXT PRIMARY KEY,
    origin           TEXT NOT NULL,
    run_id           TEXT REFERENCES runs (run_id) ON DELETE CASCADE,
    step             INTEGER,
    measured_at      TEXT,
    waveform         TEXT,
    algorithm        TEXT,
    scope_idn        TEXT,
    simulated        INTEGER,
    radbench_version TEXT,
    targets          INTEGER,
    snr_db           REAL,
    summary_sha256   TEXT
);
CREATE INDEX IF NOT EXISTS captures_by_run ON captures (run_id);

-- Detected targets: of a capture (`owner` its folder, step 0) or of a run's step (`owner` the
-- run id).
CREATE TABLE IF NOT EXISTS targets (
    owner     TEXT NOT NULL,
    step      INTEGER NOT NULL,
    algorithm TEXT NOT NULL,
    idx       INTEGER NOT NULL,
    range_m   REAL NOT NULL,
    level_db  REAL,
    PRIMARY KEY (owner, step, algorithm, idx)
) WITHOUT ROWID;

-- Response calibrations runs corrected with, by SHA-256 of their header.
CREATE TABLE IF NOT EXISTS calibrations (
    sha256      TEXT PRIMARY KEY,
    mode        TEXT NOT NULL,
    path        TEXT NOT NULL,
    measured_at TEXT NOT NULL
);

-- `*IDN?` of each instrument of a run or capture (`owner`: run id or capture folder).
CREATE TABLE IF NOT EXISTS instruments (
    owner TEXT NOT NULL,
    role  TEXT NOT NULL,
    idn   TEXT NOT NULL,
    PRIMARY KEY (owner, role)
) WITHOUT ROWID;

-- Every file a run or capture holds, with its size and SHA-256 (`owner`: run id or capture
-- folder; `path` absolute).
CREATE TABLE IF NOT EXISTS assets (
    path   TEXT PRIMARY KEY,
    owner  TEXT NOT NULL,
    bytes  INTEGER NOT NULL,
    sha256 TEXT NOT NULL,
    mtime_ns INTEGER
);
CREATE INDEX IF NOT EXISTS assets_by_owner ON assets (owner);
CREATE INDEX IF NOT EXISTS assets_by_sha256 ON assets (sha256);

-- Outputs of `radbench process --from-catalog` and the Python package's Dask path, addressed by
-- content: one row per (input, processing options, radbench version) and output folder.
CREATE TABLE IF NOT EXISTS processed (
    input_sha256     TEXT NOT NULL,
    options_sha256   TEXT NOT NULL,
    radbench_version TEXT NOT NULL,
    out_dir          TEXT NOT NULL,
    input_dir        TEXT NOT NULL,
    options          TEXT NOT NULL,
    PRIMARY KEY (input_sha256, options_sha256, radbench_version, out_dir)
) WITHOUT ROWID;
CREATE INDEX IF NOT EXISTS processed_by_input ON processed (input_dir);
