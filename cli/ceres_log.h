// Where Ceres' log lines go. Ceres logs through glog, which, left alone, writes every warning and
// error to stderr ("WARNING: Logging before InitGoogleLogging() is written to STDERR", then e.g.
// "E... covariance_impl.cc:772] Error: Covariance matrix is near rank deficient ..."): lines a
// user cannot act on, in the middle of strokelab's own. RouteCeresLog sends them where
// STROKELAB_CERES_LOG says, at the level it says, and nowhere else:
//
//   STROKELAB_CERES_LOG=off              (the default) dropped
//   STROKELAB_CERES_LOG=LEVEL            error | warning | info and above, on stderr, each line
//                                        "ceres: ERROR covariance_impl.cc:772] ..."
//   STROKELAB_CERES_LOG=LEVEL:FILE       the same lines appended to FILE instead
//
// `strokelab serve` writes them as JSON lines like the rest of its log
// ({"event":"ceres","ts_ms":...,"level":"error","source":"covariance_impl.cc:772","message":...}).
// A FATAL line (a broken Ceres invariant, which aborts) still reaches stderr whatever the setting.
#pragma once

#include <string>

namespace strokelab::cli {

struct CeresLogSettings {
  bool enabled = false;
  int min_severity = 0;  // glog's: 0 info, 1 warning, 2 error
  std::string file;      // empty: stderr
  bool json_lines = false;
};

// The settings a value of STROKELAB_CERES_LOG asks for (nullptr or empty: off); InputError naming
// STROKELAB_CERES_LOG for anything else.
CeresLogSettings CeresLogSettingsFrom(const char* value);

// Initialises glog once per process (no log files, nothing on stderr below FATAL) and routes its
// lines per `settings`. A second call replaces the settings (serve switches to JSON lines).
void RouteCeresLog(const CeresLogSettings& settings);

}  // namespace strokelab::cli
