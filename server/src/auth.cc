#include "strokelab/server/auth.h"

#include <fstream>
#include <sstream>

#include "strokelab/base/errors.h"

namespace strokelab::server {

bool ConstantTimeEquals(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char difference = 0;
  for (size_t i = 0; i < a.size(); ++i) difference |= static_cast<unsigned char>(a[i] ^ b[i]);
  return difference == 0;
}

TokenTable TokenTable::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot read the token file");
  TokenTable table;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const std::string where = path + ":" + std::to_string(number);
    std::istringstream fields(line);
    std::string role, token, extra;
    if (!(fields >> role) || role[0] == '#') continue;
    if (!(fields >> token) || (fields >> extra))
      throw InputError(where, "expected 'ROLE TOKEN' (roles: submit, read, worker)");
    if (token.size() < 16) throw InputError(where, "token too short (at least 16 characters)");
    Entry entry{Role::kRead, token};
    if (role == "submit") entry.role = Role::kSubmit;
    else if (role == "worker") entry.role = Role::kWorker;
    else if (role != "read") throw InputError(where, "unknown role '" + role + "' (roles: submit, read, worker)");
    table.entries_.push_back(entry);
  }
  if (table.entries_.empty()) throw InputError(path, "no tokens in the token file");
  return table;
}

std::optional<Role> TokenTable::Lookup(const std::string& token) const {
  std::optional<Role> found;
  // Every entry is compared, match or not, so that timing does not reveal which one matched.
  for (const Entry& e : entries_)
    if (ConstantTimeEquals(e.token, token) && !found) found = e.role;
  return found;
}

bool TokenTable::Allows(Role role, Role required) {
  switch (required) {
    case Role::kRead: return role == Role::kRead || role == Role::kSubmit;  // workers see tasks only
    case Role::kWorker: return role == Role::kWorker;  // results come from worker tokens alone
    case Role::kSubmit: return role == Role::kSubmit;
  }
  return false;
}

}  // namespace strokelab::server
