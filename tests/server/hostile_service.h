// The service in process for the hostile-request tests (hostile_input_test.cc, hostile_http_test.cc):
// no workers of its own (tasks wait for a remote lease), a token of each role, options to set
// before Start().
#pragma once

#include <gtest/gtest.h>
#include <httplib.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "strokelab/server/service.h"
#include "test_tokens.h"
#include "test_util.h"

namespace strokelab::server {

using ::strokelab::testing::kReadToken;
using ::strokelab::testing::kSubmitToken;
using ::strokelab::testing::kWorkerToken;

inline const nlohmann::json kOneTaskSimulate = {
    {"kind", "simulate"}, {"model", "paper"},         {"frequency_hz", 8}, {"amplitude_v", 0.5},
    {"duration_s", 1},    {"sample_rate_hz", 1000}, {"method", "exact"}};

// A service with no workers of its own (tasks wait for a remote lease) and a token of each role.
class HostileServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::strokelab::testing::FreshTestDir("hostile_test");
    std::ofstream(dir_ / "tokens") << "submit " << kSubmitToken << "\nread " << kReadToken << "\nworker "
                                   << kWorkerToken << "\n";
    options_.port = 0;
    options_.db_path = (dir_ / "jobs.db").string();
    options_.workers = 0;
    options_.token_file = (dir_ / "tokens").string();
    options_.quiet = true;
  }
  void Start() {
    service_ = std::make_unique<Service>(options_);
    port_ = service_->Start();
  }
  void TearDown() override {
    if (service_) service_->Stop();
    std::filesystem::remove_all(dir_);
  }
  httplib::Client Client() { return httplib::Client("127.0.0.1", port_); }
  static httplib::Headers Auth(const char* token) { return {{"Authorization", std::string("Bearer ") + token}}; }

  int64_t Submit(const nlohmann::json& job) {
    auto r = Client().Post("/v1/jobs", Auth(kSubmitToken), job.dump(), "application/json");
    if (!r || r->status != 201) throw std::runtime_error("submit: " + (r ? r->body : std::string("no reply")));
    return nlohmann::json::parse(r->body).at("id").get<int64_t>();
  }
  nlohmann::json Lease() {
    auto r = Client().Post("/v1/tasks/lease", Auth(kWorkerToken), "{}", "application/json");
    if (!r || r->status != 200) throw std::runtime_error("lease: " + (r ? r->body : std::string("no reply")));
    return nlohmann::json::parse(r->body);
  }
  // POST /v1/tasks/{id}/complete under `task`'s lease with `rows` (text, so that it may be anything).
  httplib::Result Complete(const nlohmann::json& task, const std::string& rows_text) {
    const std::string body = "{\"job_id\":" + task.at("job_id").dump() + ",\"lease_token\":" +
                             task.at("lease_token").dump() + ",\"rows\":" + rows_text + "}";
    return Client().Post("/v1/tasks/" + task.at("task_id").dump() + "/complete", Auth(kWorkerToken), body,
                         "application/json");
  }
  nlohmann::json JobStatus(int64_t id) {
    auto r = Client().Get("/v1/jobs/" + std::to_string(id), Auth(kReadToken));
    return r && r->status == 200 ? nlohmann::json::parse(r->body) : nlohmann::json();
  }
  static std::string ErrorCode(const httplib::Result& r) {
    if (!r) return "no reply";
    const nlohmann::json body = nlohmann::json::parse(r->body, nullptr, false);
    return std::to_string(r->status) + " " + (body.is_object() && body.contains("error") ? body["error"].value("code", "") : "");
  }

  std::filesystem::path dir_;
  ServiceOptions options_;
  std::unique_ptr<Service> service_;
  int port_ = 0;
};

}  // namespace strokelab::server
