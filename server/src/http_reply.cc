// Replies and the mapping of exceptions to error replies (http_reply.h).
#include "http_reply.h"

#include <atomic>

#include "archive.h"
#include "event_log.h"
#include "now.h"
#include "strokelab/base/errors.h"
#include "strokelab/jobs/campaigns.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/server/store.h"

namespace strokelab::server::internal {
namespace {

using nlohmann::json;

// "i-<ms>-<n>": unique within this process's log, and sortable by time.
std::string NewIncidentId() {
  static std::atomic<uint64_t> count{0};
  return "i-" + std::to_string(NowMs()) + "-" + std::to_string(++count);
}

HttpError Internal(const std::string& what, const httplib::Request& req) {
  const std::string incident = NewIncidentId();
  WriteLogLine({{"event", "internal_error"},
                {"time", IsoTime(NowMs())},
                {"incident", incident},
                {"method", req.method},
                {"path", req.path},
                {"what", what}});
  return {500, "internal", "internal error; the service's log names incident " + incident, "", incident};
}

}  // namespace

void SendError(httplib::Response& res, const HttpError& e) {
  json body = {{"error", {{"code", e.code}, {"message", e.message}}}};
  if (!e.field.empty()) body["error"]["field"] = e.field;
  if (!e.incident.empty()) body["error"]["incident"] = e.incident;
  res.status = e.status;
  // Messages may quote what the client sent, which need not be UTF-8.
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

void SendJson(httplib::Response& res, const json& body, int status) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

HttpError ErrorReply(const std::exception_ptr& error, const httplib::Request& req) {
  try {
    std::rethrow_exception(error);
  } catch (const HttpError& e) {
    return e;
  } catch (const StoreError& e) {
    return {503, "storage_error", e.what(), ""};
  } catch (const ArchiveError& e) {
    return {400, "bad_archive", e.bare_message(), e.field()};
  } catch (const jobs::CampaignError& e) {
    return {400, "invalid_campaign", e.bare_message(), e.field()};
  } catch (const jobs::JobLimitError& e) {
    return {400, "job_too_large", e.bare_message(), e.field()};
  } catch (const InputError& e) {
    return {400, "invalid_job", e.bare_message(), e.field()};
  } catch (const std::exception& e) {
    return Internal(e.what(), req);
  } catch (...) {
    return Internal("an exception that is not a std::exception", req);
  }
}

}  // namespace strokelab::server::internal
