-- strokelab job store, schema version 5: how many times each task spent its work budget (issue 15).
-- A task whose computation ends with a spent budget (engine steps, switches, iterations) goes back
-- to the queue once; the second time fails its job (server/src/store_tasks.cc, FailTaskOnBudget), so
-- that a model no engine can finish does not take worker after worker.
-- Applied inside one transaction together with `PRAGMA user_version = 5`.

ALTER TABLE tasks ADD COLUMN budget_failures INTEGER NOT NULL DEFAULT 0;
