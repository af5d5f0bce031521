// Hostile requests against the service in process (issue 15): deep JSON in a completion, roles and
// forged rows, security headers and methods. The slow-client, header and body-size attacks, which
// need raw sockets, are in hostile_http_test.cc.
#include "hostile_service.h"

#include <gtest/gtest.h>

#include <string>

namespace strokelab::server {
namespace {

using nlohmann::json;

class HostileInputTest : public HostileServiceTest {};

// Item 1: 70,000 levels under a valid lease overflowed the stack when the rows were copied.
TEST_F(HostileInputTest, DeepValuesInACompletionAreRefusedAsTheyAreParsed) {
  Start();
  const int64_t id = Submit(kOneTaskSimulate);
  const json task = Lease();
  const std::string deep = std::string(70000, '[') + std::string(70000, ']');
  EXPECT_EQ(ErrorCode(Complete(task, R"([{"table":"records","values":{"x":)" + deep + "}}]")), "400 bad_json");
  EXPECT_EQ(JobStatus(id).value("status", ""), "running") << "nothing was written";
  EXPECT_EQ(Client().Get("/v1/health")->status, 200);
}

}  // namespace
}  // namespace strokelab::server
