// The strokelab service: a REST API over the job store, and an in-process pool of workers that
// lease tasks from it.
//
//   POST   /v1/jobs                        submit (JSON job, validated against schema/job.schema.json)
//   GET    /v1/jobs?limit=&before=         list, newest first
//   GET    /v1/jobs/{id}                   status, progress, timings, error
//   DELETE /v1/jobs/{id}                   cancel
//   GET    /v1/jobs/{id}/points            steady states (filters, paging; JSON or CSV)
//   GET    /v1/jobs/{id}/saturation-map    threshold curve and jump intervals (JSON; ?format=svg: picture)
//   GET    /v1/jobs/{id}/frf?amplitude_v=  FRF branches at one amplitude (?format=svg: |H| family)
//   GET    /v1/jobs/{id}/result            a fit or diagnose job's result document (JSON)
//   GET    /v1/jobs/{id}/report[/FILE]     a diagnose job's HTML report (and the files it links)
//   POST   /v1/campaigns                   upload a campaign (tar or zip body) for fit and diagnose jobs
//   POST   /v1/tasks/lease, /v1/tasks/{id}/complete, /v1/tasks/{id}/fail   remote workers
//   GET    /v1/campaigns/{sha256}          a leased fit or diagnose task's campaign, for its remote worker
//   GET    /v1/health, /metrics, /         health, Prometheus text, the web page
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "strokelab/base/errors.h"  // FieldError

namespace strokelab::server {

struct ServiceOptions {
  std::string host = "127.0.0.1";  // loopback unless told otherwise
  int port = 8080;                  // 0: any free port
  std::string db_path = "var/strokelab.db";
  int workers = -1;                 // in-process workers; -1: one per core; 0: remote workers only
  std::string token_file;           // empty: no authentication (loopback use)
  size_t max_body_bytes = 1 << 20;  // larger request bodies get 413 (except campaign uploads)
  size_t max_campaign_bytes = size_t{256} << 20;  // larger campaign uploads (POST /v1/campaigns) get 413
  // Storage quotas of uploads (issue 15): the unpacked bytes one upload may keep (an archive holding
  // more is 400 bad_archive) and all uploads together (an upload that would pass it is 507
  // storage_quota; uploads are never deleted by the server).
  uint64_t upload_quota_bytes = uint64_t{256} << 20;
  uint64_t uploads_total_quota_bytes = uint64_t{4} << 30;
  // The longest wall time a job may ask for [s]: a diagnose job's max_seconds and a fit's
  // max_refinement_seconds above it are 400 at that field; a job without one gets
  // min(its default, this) (diagnose 600 s, fit 120 s) (issue 15: up to 3600 s per job were accepted).
  double max_job_seconds = 600;
  // Fit and diagnose jobs may name {"campaign": {"path": P}} with P relative to this directory;
  // empty: they may only name uploads. Uploads are kept in DB_PATH.campaigns/ID/.
  std::string data_root;
  int64_t lease_ms = 120000;        // a task lease lasts this long [ms]
  bool quiet = false;               // no access log on stderr
  // Slow clients (server/src/http_gate.h): the request line and headers must arrive within this
  // [ms] (408 after it); at most this many connections from one address may be sending them (429).
  int64_t header_timeout_ms = 10000;
  int max_pending_per_address = 32;
  int http_threads = 8;            // serve requests whose headers are in (plus 2 for health and leases)

  // Nothing, or the wrong field (port, workers, lease_ms, max_body_bytes, max_campaign_bytes,
  // upload_quota_bytes, uploads_total_quota_bytes, max_job_seconds, data_root, db_path,
  // header_timeout_ms, max_pending_per_address, http_threads).
  std::optional<FieldError> IsValid() const;
};

class Service {
 public:
  // Validates the options (InputError naming the field), opens the store (throws std::runtime_error
  // naming the file) and loads the tokens (throws strokelab::InputError naming the file and line).
  explicit Service(const ServiceOptions& options);
  ~Service();

  // Binds and starts serving and working in background threads; throws std::runtime_error if the
  // address cannot be bound. Returns the bound port.
  int Start();
  // Blocks until Stop() (from another thread or a signal handler's thread).
  void Wait();
  void Stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace strokelab::server
