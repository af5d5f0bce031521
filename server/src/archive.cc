#include "archive.h"

#include <algorithm>

namespace strokelab::server {

std::string MemberWhere(size_t index, std::string_view name) {
  return "member " + std::to_string(index + 1) + (name.empty() ? "" : " '" + std::string(name) + "'");
}

std::string NormaliseMemberName(std::string_view name, const std::string& where, const ArchiveLimits& limits) {
  if (name.empty()) throw ArchiveError(where + ": empty name");
  if (name.front() == '/') throw ArchiveError(where + ": absolute name (members must be relative)");
  std::string out;
  size_t start = 0;
  while (start <= name.size()) {
    const size_t slash = std::min(name.size(), name.find('/', start));
    const std::string_view part = name.substr(start, slash - start);
    start = slash + 1;
    if (part.empty() || part == ".") continue;
    if (part == "..") throw ArchiveError(where + ": '..' in the name (members must stay inside the archive)");
    for (char c : part)
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f || c == '\\')
        throw ArchiveError(where + ": control character or backslash in the name");
    if (!out.empty()) out += '/';
    out += part;
  }
  if (out.size() > limits.max_name_bytes)
    throw ArchiveError(where + ": name longer than " + std::to_string(limits.max_name_bytes) + " bytes");
  return out;
}

bool MemberTally::Add(const std::string& where, const std::string& path, bool directory, uint64_t bytes) {
  if (directory && bytes != 0) throw ArchiveError(where + ": a directory with data");
  if (path.empty()) {
    if (!directory) throw ArchiveError(where + ": a file without a name");
    return false;  // "./"
  }
  if (bytes > limits_.max_file_bytes)
    throw ArchiveError(where + ": " + std::to_string(bytes) + " bytes, over the limit of " +
                       std::to_string(limits_.max_file_bytes) + " bytes per file");
  total_bytes_ += bytes;
  if (total_bytes_ > limits_.max_total_bytes)
    throw ArchiveError("the members hold more than " + std::to_string(limits_.max_total_bytes) + " bytes");
  if (seen_.count(path) != 0) {
    if (directory && directories_may_repeat_) return false;
    throw ArchiveError(where + ": the name appears twice");
  }
  if (seen_.size() >= limits_.max_members)
    throw ArchiveError("more than " + std::to_string(limits_.max_members) + " members");
  seen_.insert(path);
  return true;
}

}  // namespace strokelab::server
