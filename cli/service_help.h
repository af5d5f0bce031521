// The --help texts of the service's client commands and the remote worker (cmd_service.cc).
#pragma once

namespace strokelab::cli {

// What every client command says about finding the server and the token.
#define STROKELAB_CLIENT_CONNECTION_HELP                                                                   \
  "  --server URL   the server, http://HOST:PORT          [$STROKELAB_SERVER, else http://127.0.0.1:8080]\n" \
  "  --token T      bearer token of a server started with --token-file   [$STROKELAB_TOKEN]\n"

inline constexpr const char* kSubmitHelp =
    "usage: strokelab submit JOB.json [--server URL] [--token T] [--wait]\n"
    "\n"
    "Submits a job file (a sweep, simulate, fit or diagnose job; schema/job.schema.json) and prints\n"
    "its id on stdout.\n"
    "\n" STROKELAB_CLIENT_CONNECTION_HELP
    "  --wait         follow the job until it finishes (a progress bar on a terminal); exit code 0\n"
    "                 if it succeeded, 1 if it failed or was cancelled\n"
    "\n"
    "Exit codes: 0 submitted, 2 the server refused the job as invalid (the line names the file and\n"
    "the JSON pointer of the field), 1 anything else (server unreachable, token refused).\n";

inline constexpr const char* kStatusHelp =
    "usage: strokelab status JOB_ID [--server URL] [--token T] [--wait]\n"
    "\n"
    "Prints a job's status as JSON: kind, status (queued, running, succeeded, failed, cancelled),\n"
    "progress {done, total} in tasks, timings and error.\n"
    "\n" STROKELAB_CLIENT_CONNECTION_HELP
    "  --wait         poll until the job finishes (a progress bar on a terminal), then print it\n";

inline constexpr const char* kResultsHelp =
    "usage: strokelab results JOB_ID [--csv] [--branch up|down|unstable] [--amplitude-v V]\n"
    "                        [--server URL] [--token T]\n"
    "\n"
    "Prints a finished job's results on stdout. A sweep job: its steady states, one row per grid\n"
    "point and branch, as {\"points\": [...]} or as CSV (the server's CSV stream of every row,\n"
    "GET /v1/jobs/ID/points?format=csv, written out as it arrives). A fit or diagnose\n"
    "job: its result document as JSON (as strokelab fit --json / strokelab diagnose print it).\n"
    "\n" STROKELAB_CLIENT_CONNECTION_HELP
    "  --csv          a sweep's points as CSV\n"
    "  --branch B     only the up, down or unstable branch (sweep jobs)\n"
    "  --amplitude-v V  only the grid amplitude V (sweep jobs)\n"
    "\n"
    "Exit codes: 0 printed, 2 a flag that does not apply to the job's kind, 1 anything else (the\n"
    "job is not finished, unknown, or the server unreachable).\n";

inline constexpr const char* kWorkerHelp =
    "usage: strokelab worker [--server URL] [--token T] [--threads N] [--name NAME] [--max-tasks N]\n"
    "                        [--exit-when-idle SECONDS] [--cache-dir DIR]\n"
    "\n"
    "A remote worker: leases tasks from a server over HTTP, runs them and sends the results back,\n"
    "retrying while the server is unreachable (fit and diagnose tasks too: the campaign is fetched\n"
    "from the server). Ctrl-C stops it after the tasks it runs. Polls of an\n"
    "empty queue back off from 0.5 s to 10 s on one kept-alive connection.\n"
    "\n"
    "  --server URL   the server, http://HOST:PORT          [$STROKELAB_SERVER, else http://127.0.0.1:8080]\n"
    "  --token T      a token of the worker role           [$STROKELAB_TOKEN]\n"
    "  --threads N    tasks run side by side (1 .. 256)                                [1]\n"
    "  --name NAME    the name the server records for its leases                       [HOST-PID]\n"
    "  --max-tasks N  exit after N tasks                                               [no limit]\n"
    "  --exit-when-idle SECONDS  exit once no task has been leased or run for SECONDS (a batch\n"
    "                 job's worker then frees its allocation, e.g. under Slurm)          [never]\n"
    "  --cache-dir DIR  where the campaigns of fit and diagnose tasks are kept, fetched from the\n"
    "                 server by their SHA-256 and checked against it; a directory that cannot be\n"
    "                 created leaves those tasks to other workers (said at the start)\n"
    "                 [$XDG_CACHE_HOME/strokelab/campaigns, else ~/.cache/strokelab/campaigns]\n";

#undef STROKELAB_CLIENT_CONNECTION_HELP

}  // namespace strokelab::cli
