// A small, strict reader of ZIP archives (PKWARE APPNOTE 6.3), for campaign uploads
// (POST /v1/campaigns), as ustar.h is for tar. Only what a campaign needs is accepted:
//
//   layout      the End of central directory record (searched back over a comment of up to 64 KiB),
//               on disk 0 of a single-disk archive; the central directory right before it; each
//               member's local header must agree with its central entry (name, flags, method,
//               CRC-32 and sizes), its data may not run into the central directory nor overlap
//               another member's (the overlapping-file zip bomb);
//   members     regular files and directories (a name ending in '/'); a Unix mode (external
//               attributes, high 16 bits, host 3 or 19) of a symbolic link, device, FIFO or socket
//               is refused, so nothing extracted can point outside the upload;
//   names       as for tar (archive.h): no absolute names, "..", backslashes, control characters,
//               no name twice (a directory neither);
//   data        methods 0 (stored) and 8 (deflate, zlib); encryption (flag bits 0, 6, 13), other
//               methods and flags, zip64 (never needed under the limits) and multi-disk archives
//               are refused; a data descriptor (flag bit 3) must match the central directory; the
//               CRC-32 and both sizes of every member are checked;
//   bombs       declared sizes meet the limits before anything is inflated; a member inflating to
//               over 1 MiB may do so to at most limits.max_ratio times its compressed size; inflating
//               stops one byte past the declared size, so no stream allocates past the limits.
//
// Every failure throws ArchiveError (archive.h: an InputError with field "archive") whose message
// names the member (its position in the central directory and name) and what is wrong. Member data
// are owned: inflated, or copied when stored.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "archive.h"

namespace strokelab::server {

struct ZipMember {
  std::string path;       // normalised relative path, '/'-separated, no "." or ".." components
  bool directory = false;
  std::string data;       // the member's bytes; empty for directories
};

// Whether `archive` starts like a zip: a local header "PK\3\4" or, empty, an end record "PK\5\6".
bool LooksLikeZip(std::string_view archive);

// The members of `archive` in central directory order. Throws ArchiveError.
std::vector<ZipMember> ReadZip(std::string_view archive, const ArchiveLimits& limits = {});

}  // namespace strokelab::server
