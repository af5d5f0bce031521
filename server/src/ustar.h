// A small, strict reader of tar archives in the POSIX ustar format (POSIX.1-1988, with the pax
// extended headers of POSIX.1-2001 and GNU long names that common tar writers add), for campaign
// uploads (POST /v1/campaigns). Only what a campaign needs is accepted:
//
//   members     regular files ('0', '\0', '7') and directories ('5'); every other type (hard and
//               symbolic links, devices, FIFOs, sparse files) is refused, so nothing extracted can
//               point outside the upload;
//   names       prefix "/" name (ustar), or a pax "path" record, or a GNU 'L' long name; a leading
//               "./" and empty or "." components are dropped; absolute names, ".." components,
//               backslashes and control characters are refused, as is a name given twice;
//   headers     magic "ustar"; the checksum (the unsigned byte sum of the header with the checksum
//               field read as spaces; the historic signed sum is accepted too) must match; numeric
//               fields are octal (base-256 sizes, over 8 GiB, are refused);
//   end         the archive must end with a zero block; a member whose data runs past the end is
//               truncated and refused.
//
// Every failure throws ArchiveError (archive.h: an InputError with field "archive") whose message
// names the member (its position and name) and what is wrong. The reader copies nothing: member
// data are views into the archive.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "archive.h"

namespace strokelab::server {

struct TarMember {
  std::string path;       // normalised relative path, '/'-separated, no "." or ".." components
  bool directory = false;
  std::string_view data;  // into the archive; empty for directories
};

// The members of `archive` in archive order. Throws ArchiveError.
std::vector<TarMember> ReadUstar(std::string_view archive, const ArchiveLimits& limits = {});

}  // namespace strokelab::server
