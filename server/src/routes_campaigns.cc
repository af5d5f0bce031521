// A campaign for the remote worker that runs a fit or diagnose task on it: GET /v1/campaigns/{sha256}
// with a worker token and the task's lease (headers X-Strokelab-Task, X-Strokelab-Job and
// X-Strokelab-Lease: the task id, its job id and the lease token from POST /v1/tasks/lease) returns
// the campaign's bundle (jobs/campaign_bundle.h), which the worker checks against the hash. Only a
// held lease on a task whose campaign has that hash is served, so a worker token reads no other
// campaign (403), and a campaign changed on the server's disk since the job was planned is 409.
#include <charconv>

#include "http_reply.h"
#include "now.h"
#include "service_impl.h"
#include "strokelab/jobs/campaign_bundle.h"
#include "strokelab/jobs/sha256.h"

namespace strokelab::server {

using nlohmann::json;
using namespace internal;

namespace {

int64_t HeaderId(const httplib::Request& req, const char* name) {
  const std::string text = req.get_header_value(name);
  int64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size())
    throw HttpError{403, "no_lease",
                    "a campaign is sent to the worker holding the lease on a task that needs it: send the headers "
                    "X-Strokelab-Task, X-Strokelab-Job and X-Strokelab-Lease of that lease",
                    name};
  return value;
}

}  // namespace

void Service::Impl::AddCampaignRoutes() {
  On("GET", R"(/v1/campaigns/([0-9a-f]{64}))", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
       const std::string hash = req.matches[1];
       TaskLease lease;
       lease.task_id = HeaderId(req, "X-Strokelab-Task");
       lease.job_id = HeaderId(req, "X-Strokelab-Job");
       lease.lease_token = req.get_header_value("X-Strokelab-Lease");
       const std::optional<json> task = store->LeasedTaskSpec(lease, NowMs());
       if (!task) throw HttpError{403, "no_lease", "no lease held on that task (it expired, or the job was cancelled)", ""};
       if (task->value("campaign_sha256", std::string()) != hash)
         throw HttpError{403, "no_task_for_campaign", "the leased task does not work on campaign " + hash, ""};
       const std::string bundle = jobs::CampaignBundle(task->at("campaign_dir").get<std::string>());
       if (jobs::Sha256Hex(bundle) != hash)
         throw HttpError{409, "campaign_changed", "the campaign changed after the job was submitted; submit the job again", ""};
       res.set_header("X-Strokelab-Campaign-Sha256", hash);
       res.set_content(bundle, "application/octet-stream");
     }));
}

}  // namespace strokelab::server
