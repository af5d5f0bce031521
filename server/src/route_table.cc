// The routes as a table: registration, authorisation, and what is checked on a request's headers
// before its body is read (service_impl.h). A 200 MB upload without a token was read to its end
// before the 401, and a chunked body of any size was read before the route's limit applied: now
// the route, the token and the declared length are checked first, and a route reads its body itself
// within its own limit.
#include <algorithm>
#include <charconv>
#include <filesystem>

#include "http_reply.h"
#include "service_impl.h"
#include "strokelab/base/errors.h"

namespace strokelab::server {

using namespace internal;

constexpr size_t kMaxCompletionBytes = size_t{64} << 20;

void Service::Impl::Authorize(const httplib::Request& req, Role required) {
  if (!tokens.enabled()) return;
  const std::string header = req.get_header_value("Authorization");
  const std::string prefix = "Bearer ";
  if (header.rfind(prefix, 0) != 0)
    throw HttpError{401, "unauthorized", "missing bearer token (Authorization: Bearer TOKEN)", ""};
  const std::optional<Role> role = tokens.Lookup(header.substr(prefix.size()));
  if (!role) throw HttpError{401, "unauthorized", "unknown token", ""};
  if (!TokenTable::Allows(*role, required))
    throw HttpError{403, "forbidden",
                    required == Role::kWorker ? "only a worker token may lease and complete tasks"
                    : required == Role::kRead ? "a worker token may not read jobs or results"
                                              : "this token may not do that (needs a submit token)",
                    ""};
}

void Service::Impl::On(const std::string& method, const std::string& pattern, RoutedHandler routed) {
  Register(method, pattern, routed.role, std::move(routed.handler));
}

void Service::Impl::On(const std::string& method, const std::string& pattern, httplib::Server::Handler open) {
  Register(method, pattern, std::nullopt, std::move(open));
}

void Service::Impl::Register(const std::string& method, const std::string& pattern, std::optional<Role> role,
                             httplib::Server::Handler handler) {
  // A completion may carry a diagnosis with its maps (several MiB on large campaigns and maps).
  const size_t max_body = method != "POST"                   ? 0
                          : pattern == "/v1/campaigns"       ? options.max_campaign_bytes
                          : pattern.ends_with("/complete")   ? std::max(options.max_body_bytes, kMaxCompletionBytes)
                                                             : options.max_body_bytes;
  routes.push_back({std::regex(pattern), method, role, max_body});
  if (method == "GET") {
    http.Get(pattern, std::move(handler));
  } else if (method == "DELETE") {
    http.Delete(pattern, std::move(handler));
  } else if (method == "POST") {
    // The body is read here, within the route's limit, chunked or not (cpp-httplib 0.11 bounds only
    // a declared Content-Length, by one limit for all routes).
    http.Post(pattern, [handler = std::move(handler), max_body](const httplib::Request& req, httplib::Response& res,
                                                               const httplib::ContentReader& read_body) {
      httplib::Request with_body = req;
      bool too_large = false;
      const bool read = read_body([&](const char* data, size_t length) {
        too_large = with_body.body.size() + length > max_body;
        if (!too_large) with_body.body.append(data, length);
        return !too_large;
      });
      if (too_large || !read) {
        SendError(res, too_large ? HttpError{413, "body_too_large", "request body exceeds the limit", ""}
                                 : HttpError{400, "bad_request", "the request body could not be read", ""});
        res.set_header("Connection", "close");  // the rest of the body is never read
        return;
      }
      handler(with_body, res);
    });
  } else {
    BrokenInvariant("no route registration for method " + method);
  }
}

std::string Service::Impl::AllowedMethods(const std::string& path) const {
  std::string allowed;
  for (const RouteEntry& route : routes)
    if (std::regex_match(path, route.pattern) && allowed.find(route.method) == std::string::npos)
      allowed += (allowed.empty() ? "" : ", ") + route.method;
  return allowed;
}

std::string Service::Impl::WithoutServerPaths(std::string text) const {
  const auto replace = [&text](const std::filesystem::path& dir, const std::string& name) {
    if (dir.empty()) return;
    std::error_code error;
    for (const std::filesystem::path& form : {std::filesystem::absolute(dir, error), std::filesystem::weakly_canonical(dir, error)}) {
      const std::string prefix = form.string();
      if (prefix.size() < 2) continue;
      for (size_t at; (at = text.find(prefix)) != std::string::npos;) text.replace(at, prefix.size(), name);
    }
  };
  replace(campaigns.uploads, "<uploads>");
  replace(campaigns.data_root, "<data-root>");
  replace(std::filesystem::path(options.db_path).parent_path(), "<db-dir>");
  return text;
}

Service::Impl::RoutedHandler Service::Impl::Route(Role required,
                                                  std::function<void(const httplib::Request&, httplib::Response&)> h) {
  const auto Scrubbed = [this](HttpError e) {
    e.message = WithoutServerPaths(e.message);
    e.field = WithoutServerPaths(e.field);
    return e;
  };
  return {required, [this, required, h, Scrubbed](const httplib::Request& req, httplib::Response& res) {
            const auto start = std::chrono::steady_clock::now();
            try {
              h(req, res);
              // A write route that answered with content wrote to the store.
              if (required != Role::kRead && res.status < 300 && res.status != 204) storage.WriteSucceeded();
            } catch (const StoreError& e) {
              storage.WriteFailed(e.what(), NowMs());
              SendError(res, Scrubbed(ErrorReply(std::current_exception(), req)));
            } catch (...) {
              SendError(res, Scrubbed(ErrorReply(std::current_exception(), req)));
            }
            metrics.ObserveRequest(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
          }};
}

httplib::Server::HandlerResponse Service::Impl::RefuseBeforeBody(const httplib::Request& req, httplib::Response& res) {
  const bool body_follows = req.has_header("Transfer-Encoding") ||
                            (req.has_header("Content-Length") && req.get_header_value("Content-Length") != "0");
  try {
    const std::string method = req.method == "HEAD" ? "GET" : req.method;
    const RouteEntry* route = nullptr;
    for (const RouteEntry& r : routes)
      if (r.method == method && std::regex_match(req.path, r.pattern)) route = &r;
    if (!route) {
      const std::string allowed = AllowedMethods(req.path);
      if (allowed.empty()) throw HttpError{404, "not_found", "no such endpoint", ""};
      res.set_header("Allow", allowed);
      throw HttpError{405, "method_not_allowed", req.method + " is not allowed here; allowed: " + allowed, ""};
    }
    if (route->role) Authorize(req, *route->role);
    const std::string encoding = req.get_header_value("Content-Encoding");
    if (!encoding.empty() && encoding != "identity")  // a small compressed body may inflate without bound
      throw HttpError{415, "unsupported_media_type", "send the body uncompressed (Content-Encoding: " + encoding + ")", ""};
    const std::string type = req.get_header_value("Content-Type");
    if (body_follows && type.rfind("multipart/", 0) == 0)
      throw HttpError{415, "unsupported_media_type", "multipart bodies are not accepted ('" + type + "')", ""};
    if (req.has_header("Transfer-Encoding") && req.get_header_value("Transfer-Encoding") != "chunked")
      throw HttpError{400, "bad_request", "the only transfer encoding accepted is chunked", ""};
    if (req.has_header("Transfer-Encoding") && route->max_body_bytes == 0)
      throw HttpError{413, "body_too_large", "this endpoint takes no request body", ""};
    if (req.has_header("Content-Length")) {
      const std::string text = req.get_header_value("Content-Length");
      uint64_t length = 0;
      const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), length);
      if (ec != std::errc() || end != text.data() + text.size())
        throw HttpError{400, "bad_request", "Content-Length is not a whole number", ""};
      if (length > route->max_body_bytes)
        throw HttpError{413, "body_too_large",
                        route->max_body_bytes == 0 ? "this endpoint takes no request body" : "request body exceeds the limit",
                        ""};
    }
    return httplib::Server::HandlerResponse::Unhandled;
  } catch (const HttpError& e) {
    SendError(res, e);
    if (body_follows) res.set_header("Connection", "close");  // the body is never read
    return httplib::Server::HandlerResponse::Handled;
  }
}

}  // namespace strokelab::server
