-- strokelab job store, schema version 4: each job counts its stored "points" rows, kept by the
-- store in the transaction that stores them (a task's completion, or its rows from the result
-- cache at submission). A job's state change records that count in job_events.points without
-- counting the job's result rows, which took a scan of up to a million rows inside the write
-- transaction that finished a large sweep. Jobs stored under version 3 get their count now.
-- Applied inside one transaction together with `PRAGMA user_version = 4`.

ALTER TABLE jobs ADD COLUMN points INTEGER NOT NULL DEFAULT 0;  -- rows of the "points" table stored

UPDATE jobs SET points = (SELECT count(*) FROM results r WHERE r.job_id = jobs.id AND r.table_name = 'points');
