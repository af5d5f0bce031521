// What the two campaign-upload readers (ustar.h, zip_reader.h) share: their error type, their
// limits, and the checks of member names and sizes, so that a tar and a zip are refused for the
// same things with the same words.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <set>
#include <string>
#include <string_view>

#include "strokelab/base/errors.h"

namespace strokelab::server {

class ArchiveError : public InputError {
 public:
  explicit ArchiveError(const std::string& message) : InputError("archive", message) {}
};

struct ArchiveLimits {
  size_t max_members = 10'000;               // files and directories
  uint64_t max_file_bytes = 1ull << 30;      // one member's data [bytes]
  uint64_t max_total_bytes = 1ull << 30;     // all members' data [bytes]
  size_t max_name_bytes = 1024;              // a member's path after normalisation [bytes]
  uint64_t max_ratio = 100;                  // zip: inflated over compressed bytes, of a member over 1 MiB and of the whole archive
};

// "member 3 'a/b.csv'": where a message says which member it is about (index counts from 0).
std::string MemberWhere(size_t index, std::string_view name);

// The normalised relative path of a member name ('/'-separated; a leading "./" and empty or "."
// components dropped), or "" for the archive root. Refuses absolute names, "..", backslashes,
// control characters and names over limits.max_name_bytes.
std::string NormaliseMemberName(std::string_view name, const std::string& where, const ArchiveLimits& limits);

// Counts members, in archive order, against the limits and refuses a name given twice.
class MemberTally {
 public:
  // `directories_may_repeat`: tar writes a directory once per --append; zip writers never repeat one.
  MemberTally(const ArchiveLimits& limits, bool directories_may_repeat)
      : limits_(limits), directories_may_repeat_(directories_may_repeat) {}
  // Whether to keep the member (false: the root "./" or a directory listed again). Throws
  // ArchiveError.
  bool Add(const std::string& where, const std::string& path, bool directory, uint64_t bytes);

 private:
  const ArchiveLimits& limits_;
  const bool directories_may_repeat_;
  std::set<std::string, std::less<>> seen_;
  uint64_t total_bytes_ = 0;
};

}  // namespace strokelab::server
