// Bearer tokens from a token file: one "ROLE TOKEN" per line (roles: submit, read, worker; blank
// lines and lines starting with # are ignored). A submit token may submit, cancel and read; a read
// token may only read; a worker token may only lease, renew, complete and fail tasks (it reads no
// jobs or results, and no other token writes results: a stolen submit token cannot forge rows). Tokens are compared in constant
// time against every entry, so the response time does not tell how much of a token was right.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace strokelab::server {

enum class Role { kRead, kWorker, kSubmit };

class TokenTable {
 public:
  TokenTable() = default;  // empty: authentication off
  // Throws strokelab::InputError("FILE:LINE", ...) on a malformed line or unknown role.
  static TokenTable Load(const std::string& path);
  bool enabled() const { return !entries_.empty(); }
  // The role of a presented token, if any.
  std::optional<Role> Lookup(const std::string& token) const;
  // Whether a role may do what needs `required`.
  static bool Allows(Role role, Role required);

 private:
  struct Entry {
    Role role;
    std::string token;
  };
  std::vector<Entry> entries_;
};

// Constant-time comparison of two strings (the length is not hidden).
bool ConstantTimeEquals(const std::string& a, const std::string& b);

}  // namespace strokelab::server
