// Hostile connections against the service in process (issue 15, items 3 and 4): clients that send
// their headers slowly or never, too many headers, bodies that are too large or never end, requests
// without a token that carry a body. On raw sockets (raw_http.h).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "hostile_service.h"
#include "raw_http.h"

namespace strokelab::server {
namespace {

using ::strokelab::testing::RawConnection;

class HostileHttpTest : public HostileServiceTest {};

// Item 3: sixteen clients trickling their headers a byte at a time (cpp-httplib's pool had eight
// threads, each held as long as the bytes kept coming) while health and lease requests are sent.
TEST_F(HostileHttpTest, HealthAndLeaseAnswerWhileSlowClientsTrickleTheirHeaders) {
  Start();
  std::vector<std::unique_ptr<RawConnection>> slow;
  for (int i = 0; i < 16; ++i) {
    slow.push_back(std::make_unique<RawConnection>(port_));
    slow.back()->Send("GET /v1/jobs HTTP/1.1\r\nHost: x\r\nX-Slow: ");
  }
  std::atomic<bool> done{false};
  std::thread trickle([&] {
    while (!done) {
      for (auto& c : slow) c->Send("a");
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  });
  // Each probe on a fresh connection, as a load balancer sends them; a probe not answered in 3 s
  // (the slow clients go on for as long as the probes take) fails.
  int answered = 0;
  for (int i = 0; i < 5; ++i) {
    httplib::Client probe("127.0.0.1", port_);
    probe.set_read_timeout(3, 0);
    auto r = probe.Get("/v1/health");
    answered += r && r->status == 200;
  }
  httplib::Client worker("127.0.0.1", port_);
  worker.set_read_timeout(3, 0);
  auto lease = worker.Post("/v1/tasks/lease", Auth(kWorkerToken), "{}", "application/json");
  done = true;
  trickle.join();
  EXPECT_EQ(answered, 5);
  ASSERT_TRUE(lease) << httplib::to_string(lease.error());
  EXPECT_EQ(lease->status, 204);  // nothing queued
}

// Item 3: headers cut off are answered 408 once the header timeout has passed (cpp-httplib waited
// for a byte for 5 s at a time, as often as one came).
TEST_F(HostileHttpTest, HeadersThatStopComingGet408) {
  options_.header_timeout_ms = 200;
  Start();
  RawConnection partial(port_);
  partial.Send("GET /v1/health HTTP/1.1\r\nHost: x\r\n");
  EXPECT_EQ(partial.Status(), 408);
  RawConnection silent(port_);
  EXPECT_EQ(silent.Status(), 408);
}

// Item 3: connections from one address that have not sent their headers are capped; connections
// kept alive between requests are not, so workers behind one address keep theirs.
TEST_F(HostileHttpTest, ConnectionsStillSendingHeadersAreCappedPerAddress) {
  options_.max_pending_per_address = 4;
  Start();
  std::vector<std::unique_ptr<httplib::Client>> kept_alive;
  for (int i = 0; i < 8; ++i) {
    kept_alive.push_back(std::make_unique<httplib::Client>("127.0.0.1", port_));
    kept_alive.back()->set_keep_alive(true);
    ASSERT_EQ(kept_alive.back()->Get("/v1/health")->status, 200);
  }
  std::vector<std::unique_ptr<RawConnection>> silent;
  for (int i = 0; i < 4; ++i) silent.push_back(std::make_unique<RawConnection>(port_));
  RawConnection one_too_many(port_);
  EXPECT_EQ(one_too_many.Status(), 429);
  for (auto& client : kept_alive) {
    auto r = client->Get("/v1/health");
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 200);
  }
}

// Item 4: 400,000 headers (40 MB) were read and kept; the header block is bounded in lines and bytes.
TEST_F(HostileHttpTest, TooManyOrTooLargeHeadersGet431) {
  Start();
  std::string many = "GET /v1/health HTTP/1.1\r\nHost: x\r\n";
  for (int i = 0; i < 200; ++i) many += "X-Header-" + std::to_string(i) + ": 1\r\n";
  RawConnection lines(port_);
  lines.Send(many + "\r\n");
  EXPECT_EQ(lines.Status(), 431);
  std::string large = "GET /v1/health HTTP/1.1\r\nHost: x\r\n";
  for (int i = 0; i < 8; ++i) large += "X-Large-" + std::to_string(i) + ": " + std::string(6000, 'a') + "\r\n";
  RawConnection bytes(port_);
  bytes.Send(large + "\r\n");
  EXPECT_EQ(bytes.Status(), 431);
  // A header flood that never ends is refused, not read to its end.
  RawConnection flood(port_);
  bool open = flood.Send("GET /v1/health HTTP/1.1\r\n");
  for (int i = 0; i < 400000 && open; ++i) open = flood.Send("X-Flood-" + std::to_string(i) + ": 1\r\n");
  EXPECT_FALSE(open) << "the server read 400,000 header lines";
}

// Sends `chunk` until the server stops taking it or `total` bytes went; the bytes sent.
size_t SendUntilRefused(RawConnection& c, const std::string& chunk, size_t total) {
  size_t sent = 0;
  while (sent < total && c.Send(chunk)) sent += chunk.size();
  return sent;
}

constexpr size_t kMiB = size_t{1} << 20;

// Item 4: a 200 MB upload without a token was read to its end before the 401 (RSS 17 -> 279 MB).
TEST_F(HostileHttpTest, AnUploadWithoutATokenIsRefusedBeforeItsBody) {
  Start();
  RawConnection upload(port_);
  upload.Send("POST /v1/campaigns HTTP/1.1\r\nHost: x\r\nContent-Type: application/x-tar\r\nContent-Length: " +
              std::to_string(200 * kMiB) + "\r\n\r\n");
  const std::string megabyte(kMiB, '\0');
  upload.Send(megabyte);
  EXPECT_EQ(upload.Status(), 401);
  EXPECT_LT(SendUntilRefused(upload, megabyte, 200 * kMiB), 120 * kMiB) << "the body was read on";
}

// Item 4: a chunked body was read in full whatever its route (cpp-httplib 0.11 bounds only a
// declared Content-Length); now each route reads within its own limit, and a route without a body
// (or a method it does not take) refuses on the headers.
TEST_F(HostileHttpTest, ChunkedBodiesAreHeldToTheirRoutesLimit) {
  Start();
  const std::string chunk = "100000\r\n" + std::string(kMiB, ' ') + "\r\n";  // 1 MiB chunks
  for (const std::string target : {"POST /v1/jobs", "POST /v1/health", "DELETE /v1/jobs/1"}) {
    RawConnection post(port_);
    post.Send(target + " HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " + kSubmitToken +
              "\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n");
    post.Send(chunk + chunk);
    EXPECT_EQ(post.Status(), target == "POST /v1/health" ? 405 : 413) << target;
    EXPECT_LT(SendUntilRefused(post, chunk, 200 * kMiB), 120 * kMiB) << target << ": the body was read on";
  }
}

// Items 4 and 7: PUT /v1/jobs without a length was read until the client gave up (400 after 5 s);
// compressed bodies (which cpp-httplib inflates without a bound) are refused.
TEST_F(HostileHttpTest, MethodsAndEncodingsAreRefusedOnTheHeaders) {
  Start();
  RawConnection put(port_);
  put.Send(std::string("PUT /v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer ") + kSubmitToken + "\r\n\r\n");
  EXPECT_EQ(put.Status(), 405);
  auto gzip = Client().Post("/v1/jobs", {{"Authorization", std::string("Bearer ") + kSubmitToken}, {"Content-Encoding", "gzip"}},
                            std::string(32, 'x'), "application/json");
  ASSERT_TRUE(gzip);
  EXPECT_EQ(gzip->status, 415);
}

}  // namespace
}  // namespace strokelab::server
