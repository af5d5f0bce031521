// Ceres' glog lines routed per STROKELAB_CERES_LOG (ceres_log.h).
#include "ceres_log.h"

#include <glog/logging.h>

#include <chrono>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "strokelab/base/errors.h"

namespace strokelab::cli {
namespace {

constexpr const char* kCeresLogVariable = "STROKELAB_CERES_LOG";
constexpr const char* kSeverityWords[] = {"info", "warning", "error", "fatal"};

// The one sink, registered once: glog calls it with its own mutex held, one line at a time.
class CeresLogSink : public google::LogSink {
 public:
  void Configure(const CeresLogSettings& settings) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (out_ && out_ != stderr) std::fclose(out_);
    out_ = nullptr;
    settings_ = settings;
    if (!settings.enabled) return;
    if (settings.file.empty()) {
      out_ = stderr;
      return;
    }
    out_ = std::fopen(settings.file.c_str(), "a");
    if (!out_) throw InputError(kCeresLogVariable, "cannot open '" + settings.file + "' for appending");
  }

  void send(google::LogSeverity severity, const char*, const char* base_filename, int line,
            const google::LogMessageTime&, const char* message, size_t message_len) override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!out_ || severity < settings_.min_severity || severity >= google::NUM_SEVERITIES) return;
    const std::string source = std::string(base_filename) + ":" + std::to_string(line);
    const std::string text(message, message_len);
    std::string out;
    if (settings_.json_lines) {
      const auto now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::system_clock::now().time_since_epoch()).count();
      const nlohmann::json entry = {{"event", "ceres"}, {"ts_ms", now_ms}, {"level", kSeverityWords[severity]},
                                    {"source", source}, {"message", text}};
      out = entry.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
    } else {
      out = "ceres: " + std::string(google::GetLogSeverityName(severity)) + " " + source + "] " + text + "\n";
    }
    std::fwrite(out.data(), 1, out.size(), out_);
    std::fflush(out_);
  }

 private:
  std::mutex mutex_;
  CeresLogSettings settings_;
  std::FILE* out_ = nullptr;
};

CeresLogSink& Sink() {
  static CeresLogSink* sink = new CeresLogSink;  // never destroyed: glog may log during exit
  return *sink;
}

}  // namespace

CeresLogSettings CeresLogSettingsFrom(const char* value) {
  CeresLogSettings settings;
  const std::string text = value ? value : "";
  if (text.empty() || text == "off") return settings;
  const size_t colon = text.find(':');
  const std::string level = text.substr(0, colon);
  settings.enabled = true;
  if (level == "info") {
    settings.min_severity = google::GLOG_INFO;
  } else if (level == "warning") {
    settings.min_severity = google::GLOG_WARNING;
  } else if (level == "error") {
    settings.min_severity = google::GLOG_ERROR;
  } else {
    throw InputError(kCeresLogVariable, "expected off, error, warning or info, optionally followed by :FILE, got '" +
                                            text + "'");
  }
  if (colon != std::string::npos) {
    settings.file = text.substr(colon + 1);
    if (settings.file.empty()) throw InputError(kCeresLogVariable, "no file after ':' in '" + text + "'");
  }
  return settings;
}

void RouteCeresLog(const CeresLogSettings& settings) {
  static std::once_flag initialised;
  std::call_once(initialised, [] {
    FLAGS_logtostderr = false;
    FLAGS_alsologtostderr = false;
    // An empty base name turns glog's log files off for that severity (else /tmp/strokelab.*.log.*).
    for (int severity = 0; severity < google::NUM_SEVERITIES; ++severity) google::SetLogDestination(severity, "");
    google::SetStderrLogging(google::GLOG_FATAL);
    google::InitGoogleLogging("strokelab");
    google::AddLogSink(&Sink());
  });
  Sink().Configure(settings);
  // Lines below this are not even formatted.
  FLAGS_minloglevel = settings.enabled ? settings.min_severity : google::GLOG_FATAL;
}

}  // namespace strokelab::cli
