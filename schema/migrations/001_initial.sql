-- strokelab job store, schema version 1: jobs, their tasks (the queue), result rows, and the
-- result cache by task key. Applied by server/src/store.cc inside one transaction together with
-- `PRAGMA user_version = 1`. Times are unix epoch milliseconds; 0 or NULL means "not yet".

CREATE TABLE jobs (
  id           INTEGER PRIMARY KEY,
  kind         TEXT    NOT NULL,                  -- "sweep", "simulate", ...
  status       TEXT    NOT NULL
               CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
  spec_json    TEXT    NOT NULL,                  -- the job spec as submitted (validated)
  tasks_total  INTEGER NOT NULL CHECK (tasks_total >= 0),
  tasks_done   INTEGER NOT NULL DEFAULT 0 CHECK (tasks_done >= 0 AND tasks_done <= tasks_total),
  created_ms   INTEGER NOT NULL,
  started_ms   INTEGER NOT NULL DEFAULT 0,        -- first lease (or completion from the cache)
  finished_ms  INTEGER NOT NULL DEFAULT 0,
  error        TEXT                               -- when failed
);
CREATE INDEX jobs_by_status ON jobs (status);

-- One row per task. A task is leasable when it is 'queued', or 'leased' with lease_expires_ms <=
-- now. lease_token is a random 128-bit hex string that changes at every lease, so a worker whose
-- lease expired and was taken over can no longer complete, renew or fail the task.
CREATE TABLE tasks (
  id               INTEGER PRIMARY KEY,
  job_id           INTEGER NOT NULL REFERENCES jobs (id),
  idx              INTEGER NOT NULL,              -- position within the job, 0-based
  key              TEXT    NOT NULL,              -- content hash: identical work has the same key
  spec_json        TEXT    NOT NULL,
  status           TEXT    NOT NULL
                   CHECK (status IN ('queued', 'leased', 'done', 'failed', 'cancelled')),
  lease_token      TEXT,
  lease_owner      TEXT,
  lease_expires_ms INTEGER NOT NULL DEFAULT 0,
  attempts         INTEGER NOT NULL DEFAULT 0,    -- leases granted so far
  finished_ms      INTEGER NOT NULL DEFAULT 0,
  UNIQUE (job_id, idx)
);
-- The queue: oldest queued task first; leased tasks are few (one per worker) and scanned for expiry.
CREATE INDEX tasks_by_status ON tasks (status, id);

-- Result rows, one per (job, table, task, row); written with the task's completion in one
-- transaction. frequency_hz, amplitude_v and branch are copied out of the row's JSON (when present)
-- so that queries can filter on them.
CREATE TABLE results (
  id           INTEGER PRIMARY KEY,
  job_id       INTEGER NOT NULL REFERENCES jobs (id),
  table_name   TEXT    NOT NULL,                  -- "points", "thresholds", "jumps", "records"
  task_idx     INTEGER NOT NULL,
  row_idx      INTEGER NOT NULL,
  frequency_hz REAL,                              -- [Hz]
  amplitude_v  REAL,                              -- drive amplitude [V]
  branch       TEXT,                              -- "up", "down", "unstable", ...
  json         TEXT    NOT NULL,
  UNIQUE (job_id, table_name, task_idx, row_idx)  -- also the paging order
);
-- Filters on one amplitude (an FRF) and on frequency ranges.
CREATE INDEX results_by_amplitude ON results (job_id, table_name, amplitude_v, frequency_hz);

-- Result rows of finished tasks by task key: a JSON array of {"table": ..., "values": {...}}.
CREATE TABLE cache (
  key        TEXT    PRIMARY KEY,
  rows_json  TEXT    NOT NULL,
  created_ms INTEGER NOT NULL
);
