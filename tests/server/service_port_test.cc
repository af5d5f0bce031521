// The service's listening socket is its own: a second service on the same port fails to start
// instead of sharing the port. (httplib's default SO_REUSEPORT let it start, and the kernel then
// split connections between the two; found by tests/fuzz/fuzz_http as requests never answered,
// when a port-0 service was handed a port another process on the machine listened on.)
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "strokelab/server/service.h"

namespace strokelab::server {
namespace {

namespace fs = std::filesystem;

ServiceOptions QuietOptions(const fs::path& db, int port) {
  ServiceOptions options;
  options.port = port;
  options.db_path = db.string();
  options.workers = 0;
  options.quiet = true;
  return options;
}

TEST(ServicePort, ASecondServiceOnTheSamePortFailsToStart) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("strokelab_service_port_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::string error;
  {
    Service first(QuietOptions(dir / "first.db", 0));
    const int port = first.Start();
    ASSERT_GT(port, 0);
    Service second(QuietOptions(dir / "second.db", port));
    try {
      second.Start();
    } catch (const std::runtime_error& e) {
      error = e.what();
    }
  }
  fs::remove_all(dir);
  EXPECT_THAT(error, ::testing::HasSubstr("cannot bind")) << "the second service started on the first one's port";
}

}  // namespace
}  // namespace strokelab::server
