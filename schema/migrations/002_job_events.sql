-- strokelab job store, schema version 2: the history of every job's state changes, one row per
-- change (queued, running, succeeded, failed, cancelled), written by server/src/store.cc in the
-- same transaction as the change itself, so the history never disagrees with jobs.status. The
-- service logs each change as one JSON line on stderr from the same event (server/src/event_log.h).
-- Applied inside one transaction together with `PRAGMA user_version = 2`.

CREATE TABLE job_events (
  id          INTEGER PRIMARY KEY,                -- order of the changes
  job_id      INTEGER NOT NULL REFERENCES jobs (id),
  at_ms       INTEGER NOT NULL,                   -- unix epoch [ms]
  status      TEXT    NOT NULL
              CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
  tasks_done  INTEGER NOT NULL DEFAULT 0,         -- of the job, at the change
  points      INTEGER NOT NULL DEFAULT 0,         -- rows of the "points" table stored, at the change
  reason      TEXT    NOT NULL DEFAULT ''         -- why: "submitted", the worker, the error, ...
);
CREATE INDEX job_events_by_job ON job_events (job_id, id);

-- Jobs stored under version 1 get the history the jobs table still tells: submitted at created_ms,
-- running from started_ms, finished at finished_ms. Ordered by job so that ids follow the history.
INSERT INTO job_events (job_id, at_ms, status, tasks_done, points, reason)
SELECT job_id, at_ms, status, tasks_done, points, reason FROM (
  SELECT id AS job_id, 0 AS step, created_ms AS at_ms, 'queued' AS status, 0 AS tasks_done, 0 AS points,
         'submitted (history from schema 1)' AS reason
  FROM jobs
  UNION ALL
  SELECT id, 1, started_ms, 'running', 0, 0, 'history from schema 1'
  FROM jobs WHERE started_ms > 0 AND status <> 'queued'
  UNION ALL
  SELECT id, 2, finished_ms, status, tasks_done,
         (SELECT count(*) FROM results r WHERE r.job_id = jobs.id AND r.table_name = 'points'),
         coalesce(error, 'history from schema 1')
  FROM jobs WHERE status IN ('succeeded', 'failed', 'cancelled')
)
ORDER BY job_id, step;
