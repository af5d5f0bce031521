// How a request ends: a JSON reply, or an error as {"error": {"code", "message", "field"}} with its
// status, chosen by the kind of the exception that ended the handler. Internal to the service.
//
//   HttpError                      its own status and code (the handlers' refusals)
//   InputError and its kinds       400 with the field (a JSON pointer, a file:line, an archive)
//   StoreError                     503 storage_error (the disk, not the request)
//   anything else                  500 internal, with an incident id that a log line on stderr
//                                  gives with the details (a bug or a damaged store, never the client)
//
// A json::exception is bad input only while the request body is parsed (JsonBody, request_params.h);
// anywhere else it is a bug and a 500.
#pragma once

#include <exception>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <string>

namespace strokelab::server::internal {

// An error that ends a request, with the status and the stable code to answer.
struct HttpError {
  int status;
  std::string code, message, field;
  std::string incident = {};  // of an internal error: the id its log line carries
};

void SendError(httplib::Response& res, const HttpError& e);
void SendJson(httplib::Response& res, const nlohmann::json& body, int status = 200);

// The reply to the exception `error` that ended the handler of `req` (see the table above). An
// internal error is logged with a new incident id, which the reply carries.
HttpError ErrorReply(const std::exception_ptr& error, const httplib::Request& req);

}  // namespace strokelab::server::internal
