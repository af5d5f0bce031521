-- strokelab job store, schema version 3: the first-order FRF's real and imaginary parts of stored
-- sweep points carry their unit in their names, as every other column does: h_re -> h_re_n_per_v,
-- h_im -> h_im_n_per_v [N/V] (report/src/sweep_tables.cc). Rows stored under version 2 are renamed
-- in place, so that a finished job reads (GET /v1/jobs/{id}/points, its pictures) as a new one
-- does. The result cache is left alone: its keys carry the code version, which changed with the
-- names, so no new task is served from an old entry.
-- Applied inside one transaction together with `PRAGMA user_version = 3`.

UPDATE results
SET json = json_remove(json_set(json, '$.h_re_n_per_v', json_extract(json, '$.h_re'),
                                      '$.h_im_n_per_v', json_extract(json, '$.h_im')),
                       '$.h_re', '$.h_im')
WHERE table_name = 'points' AND json_type(json, '$.h_re') IS NOT NULL;
