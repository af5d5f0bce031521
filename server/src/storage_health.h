// Whether the store can write, as /v1/health reports it: the last write that failed (disk full, I/O
// error, a lock held too long), until a later write succeeds. Reads keep working while writes fail
// (jobs can still be looked at), so a probe that only read would say "ok" on a full disk.
#pragma once

#include <cstdint>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

namespace strokelab::server::internal {

class StorageHealth {
 public:
  void WriteFailed(const std::string& message, int64_t now_ms) {
    std::lock_guard lock(mu_);
    if (error_.empty()) since_ms_ = now_ms;
    error_ = message;
  }
  void WriteSucceeded() {
    std::lock_guard lock(mu_);
    error_.clear();
  }
  // null when writes work; else {"message", "since_ms"}.
  nlohmann::json Problem() const {
    std::lock_guard lock(mu_);
    if (error_.empty()) return nullptr;
    return {{"message", error_}, {"since_ms", since_ms_}};
  }

 private:
  mutable std::mutex mu_;
  std::string error_;
  int64_t since_ms_ = 0;  // unix epoch [ms] of the first failure in a row
};

}  // namespace strokelab::server::internal
