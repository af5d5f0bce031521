-- strokelab job store, schema version 6: result rows are stored by block, one row per (job, table,
-- task) holding that task's rows of that table in a compact binary form (server/src/row_block.h),
-- with the ranges of the rows' filter columns so that filtered reads skip blocks unread. Schema 5
-- kept one SQL row of JSON text per result row in three B-trees, and a second JSON copy of each
-- finished task's rows in the result cache: completions were limited to ~48,000 rows per CPU-second
-- of the store (issue 17). The cache table goes too: a submitted task whose key equals a finished
-- task's (the key hashes the work and the code version) takes that task's blocks.
-- Applied inside one transaction together with `PRAGMA user_version = 6`; the store then moves the
-- rows of results into blocks and drops results and cache (server/src/store_results.cc,
-- MoveResultRowsIntoBlocks), in the same transaction.

CREATE TABLE result_blocks (
  id               INTEGER PRIMARY KEY,
  job_id           INTEGER NOT NULL REFERENCES jobs (id),
  table_name       TEXT    NOT NULL,              -- "points", "thresholds", "jumps", "records", ...
  task_idx         INTEGER NOT NULL,
  rows             INTEGER NOT NULL CHECK (rows > 0),
  frequency_min_hz REAL,                          -- [Hz] over the block's rows; NULL: none has one
  frequency_max_hz REAL,
  amplitude_min_v  REAL,                          -- drive amplitude [V], likewise
  amplitude_max_v  REAL,
  block            BLOB    NOT NULL,
  UNIQUE (job_id, table_name, task_idx)           -- also the paging order
);

-- Result cache hits: the finished tasks by key.
CREATE INDEX tasks_done_by_key ON tasks (key) WHERE status = 'done';
