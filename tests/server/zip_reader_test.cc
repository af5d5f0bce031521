// The zip reader of campaign uploads (server/src/zip_reader.h) on archives written here
// (zip_writer.h): stored and deflated members, directories and data descriptors come back as
// written; every refusal names the member and the reason; zip bombs (a stream longer than declared,
// a huge ratio, overlapping members) are refused without allocating what they claim.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/resource.h>

#include "zip_reader.h"
#include "zip_writer.h"

namespace strokelab::server {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using zip_writer::DeflatedZeros;
using zip_writer::Le;
using zip_writer::Zip;
using zip_writer::ZipEntry;

// "path=data" per member, "path/" for directories.
std::vector<std::string> Listing(const std::vector<ZipMember>& members) {
  std::vector<std::string> out;
  for (const ZipMember& m : members) out.push_back(m.directory ? m.path + "/" : m.path + "=" + m.data);
  return out;
}

// The message of the ArchiveError that reading `archive` throws ("" if none).
std::string Refusal(const std::string& archive, const ArchiveLimits& limits = {}) {
  try {
    ReadZip(archive, limits);
  } catch (const ArchiveError& e) {
    EXPECT_EQ(e.field(), "archive");
    return e.bare_message();
  }
  return "";
}

// Peak resident memory of this process [bytes].
uint64_t PeakRss() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<uint64_t>(usage.ru_maxrss) * 1024;
}

// A stored entry (method 0) with `name` and `data`.
ZipEntry Stored(std::string name, std::string data) {
  ZipEntry e(std::move(name), std::move(data));
  e.method = 0;
  return e;
}

TEST(ReadZip, StoredAndDeflatedMembersRoundTrip) {
  std::string csv;
  for (int i = 0; i < 2000; ++i) csv += std::to_string(i) + "," + std::to_string(i * 0.001) + "\n";
  ZipEntry dir{"c/", ""};
  dir.mode = 040755;
  const std::string zip = Zip({dir, Stored("c/manifest.json", "{}"), {"./c/rec.csv", csv}, {"c/empty.csv", ""}},
                              "an archive comment");
  EXPECT_TRUE(LooksLikeZip(zip));
  EXPECT_THAT(Listing(ReadZip(zip)), ElementsAre("c/", "c/manifest.json={}", "c/rec.csv=" + csv, "c/empty.csv="));
  // An empty archive is its end record alone: zip, and no members.
  EXPECT_TRUE(LooksLikeZip(Zip({})));
  EXPECT_TRUE(ReadZip(Zip({})).empty());
  EXPECT_FALSE(LooksLikeZip(std::string(1024, '\0')));
}

TEST(ReadZip, DataDescriptorsWithAndWithoutSignature) {
  ZipEntry signed_descriptor{"a.csv", "1,2\n3,4\n"}, bare_descriptor = Stored("b.csv", "5,6\n");
  signed_descriptor.descriptor = bare_descriptor.descriptor = true;
  bare_descriptor.descriptor_signature = false;
  EXPECT_THAT(Listing(ReadZip(Zip({signed_descriptor, bare_descriptor}))),
              ElementsAre("a.csv=1,2\n3,4\n", "b.csv=5,6\n"));
  // A descriptor that disagrees with the central directory (its CRC's first byte changed).
  std::string zip = Zip({signed_descriptor});
  zip[zip.find(Le(0x08074b50, 4)) + 4] ^= 1;
  EXPECT_THAT(Refusal(zip), HasSubstr("member 1 'a.csv': its data descriptor is missing or disagrees"));
}

TEST(ReadZip, RefusalsNameTheMemberAndTheReason) {
  ZipEntry encrypted{"a.csv", "x"}, bzip2 = Stored("a.csv", "x"), zip64{"a.csv", "x"}, link{"c/link", "/etc/passwd"},
      fifo{"c/fifo", ""}, unknown_flag{"a.csv", "x"}, bad_crc{"a.csv", "x"}, dir_with_data{"c/", "x"};
  encrypted.flags = 1;
  bzip2.method = 12;
  zip64.size = 0xffffffff;
  link.mode = 0120777;
  fifo.mode = 010644;
  unknown_flag.flags = 0x0010;
  bad_crc.crc = 12345;
  std::string local_disagrees = Zip({{"a.csv", "x"}});
  local_disagrees[14] ^= 1;  // the local header's CRC-32
  std::string multi_disk = Zip({{"a.csv", "x"}});
  multi_disk[multi_disk.size() - 22 + 4] = 1;  // the end record's disk number
  std::string local_zip64 = Zip({{"a.csv", "x"}}), end_zip64 = local_zip64;
  local_zip64.replace(18, 8, Le(0xffffffff, 4) + Le(0xffffffff, 4));  // what streaming writers put there
  end_zip64.replace(end_zip64.size() - 22 + 8, 4, Le(0xffff, 2) + Le(0xffff, 2));  // the entry counts
  const std::string good = Zip({{"a.csv", "x"}});
  struct Case {
    std::string name, archive, message;
  } cases[] = {
      {"encrypted", Zip({encrypted}), "member 1 'a.csv': encrypted"},
      {"method", Zip({bzip2}), "member 1 'a.csv': compression method 12"},
      {"zip64", Zip({zip64}), "member 1 'a.csv': zip64"},
      {"zip64 local header", local_zip64, "member 1 'a.csv': zip64 sizes in its local header"},
      {"zip64 end record", end_zip64, "a zip64 archive"},
      {"multi-disk", multi_disk, "a multi-disk archive"},
      {"symbolic link", Zip({Stored("c/x", "1"), link}), "member 2 'c/link': is a symbolic link (only regular files"},
      {"fifo", Zip({fifo}), "member 1 'c/fifo': is a device, FIFO or socket"},
      {"flags", Zip({unknown_flag}), "member 1 'a.csv': general-purpose flags 0x00000010"},
      {"absolute", Zip({{"/etc/cron.d/x", "x"}}), "member 1 '/etc/cron.d/x': absolute name"},
      {"dot-dot", Zip({{"c/../../x", "x"}}), "member 1 'c/../../x': '..' in the name"},
      {"backslash", Zip({{"c\\x.csv", "x"}}), "member 1 'c\\x.csv': control character or backslash"},
      {"control character", Zip({{"c/\x01.csv", "x"}}), "control character or backslash"},
      {"file twice", Zip({{"a.csv", "1"}, {"a.csv", "2"}}), "member 2 'a.csv': the name appears twice"},
      {"directory twice", Zip({{"c/", ""}, {"c/", ""}}), "member 2 'c/': the name appears twice"},
      {"directory with data", Zip({dir_with_data}), "member 1 'c/': a directory with data"},
      {"bad CRC", Zip({bad_crc}), "member 1 'a.csv': CRC-32 mismatch"},
      {"local header", local_disagrees, "member 1 'a.csv': the local header disagrees"},
      {"truncated end", good.substr(0, good.size() - 1), "no end of central directory record"},
      {"truncated data", good.substr(0, 20) + good.substr(40), "does not end where the end record starts"},
      {"too short", "PK\3\4", "less than a zip's end record"},
  };
  for (const Case& c : cases) EXPECT_THAT(Refusal(c.archive), HasSubstr(c.message)) << c.name;
}

TEST(ReadZip, DeclaredSizesMustBeTheTrueOnes) {
  const std::string data(5000, 'a');
  ZipEntry longer{"a.csv", data}, shorter{"a.csv", data}, stored = Stored("a.csv", data), trailing{"a.csv", data},
      truncated{"a.csv", data}, corrupt{"a.csv", data};
  longer.size = 4000;  // the stream holds more than declared
  shorter.size = 6000;
  stored.size = 4000;
  trailing.packed = zip_writer::Deflate(data) + "xx";
  truncated.packed = zip_writer::Deflate(data).substr(0, 5);
  corrupt.packed = "\xff\xff\xff";  // block type 3 does not exist
  EXPECT_THAT(Refusal(Zip({longer})), HasSubstr("member 1 'a.csv': inflates to more than its declared 4000 bytes"));
  EXPECT_THAT(Refusal(Zip({shorter})), HasSubstr("member 1 'a.csv': inflates to 5000 bytes, not its declared 6000"));
  EXPECT_THAT(Refusal(Zip({stored})), HasSubstr("member 1 'a.csv': stored, but its sizes differ"));
  EXPECT_THAT(Refusal(Zip({trailing})), HasSubstr("member 1 'a.csv': 2 bytes after the end of its deflate stream"));
  EXPECT_THAT(Refusal(Zip({truncated})), HasSubstr("member 1 'a.csv': truncated deflate data"));
  EXPECT_THAT(Refusal(Zip({corrupt})), HasSubstr("member 1 'a.csv': corrupt deflate data"));
}

TEST(ReadZip, LimitsAreEnforced) {
  const std::string zip = Zip({{"a.csv", std::string(1000, 'x')}, {"b.csv", "y"}, {"c/", ""}});
  ArchiveLimits limits;
  limits.max_file_bytes = 999;
  EXPECT_THAT(Refusal(zip, limits), HasSubstr("member 1 'a.csv': 1000 bytes, over the limit of 999 bytes per file"));
  limits = {};
  limits.max_total_bytes = 1000;
  EXPECT_THAT(Refusal(zip, limits), HasSubstr("the members hold more than 1000 bytes"));
  limits = {};
  limits.max_members = 2;
  EXPECT_THAT(Refusal(zip, limits), HasSubstr("more than 2 members"));
  limits = {};
  limits.max_name_bytes = 4;
  EXPECT_THAT(Refusal(zip, limits), HasSubstr("member 1 'a.csv': name longer than 4 bytes"));
  EXPECT_EQ(ReadZip(zip).size(), 3u);
}

TEST(ReadZip, ZipBombsAreRefusedWithoutAllocating) {
  constexpr size_t kMib = 1024;  // 1 GiB of zeros, about 1 MiB deflated
  const std::string zeros = DeflatedZeros(kMib);
  // Claimed small (inflating must stop one byte past the claim), and claimed honestly.
  ZipEntry small_claim{"c/rec.csv", ""};
  small_claim.packed = zeros;
  small_claim.size = 1000;
  ZipEntry honest = small_claim;
  honest.size = kMib << 20;
  // Overlapping members (one stream listed many times): a stored member holding the next one's
  // local record, both in the central directory.
  const std::string inner = Zip({{"c/b.csv", "1,2\n"}});
  const ZipEntry outer = Stored("c/a", inner.substr(0, inner.find(Le(0x02014b50, 4))));
  ZipEntry overlapping{"c/b.csv", "1,2\n"};
  overlapping.local_offset = 30 + outer.name.size();
  const std::string small_bomb = Zip({small_claim}), honest_bomb = Zip({honest}), overlap_bomb = Zip({outer, overlapping});

  const uint64_t peak_before = PeakRss();  // the archives are built: from here on only the reader allocates
  EXPECT_THAT(Refusal(small_bomb), HasSubstr("member 1 'c/rec.csv': inflates to more than its declared 1000"));
  // The ratio (over 1000) refuses the honest one before anything is inflated.
  EXPECT_THAT(Refusal(honest_bomb), HasSubstr("member 1 'c/rec.csv': inflates " + std::to_string(zeros.size()) +
                                              " bytes to 1073741824, over 100 times as many (a zip bomb)"));
  // With the ratio check lifted, the size limits still refuse it before inflating.
  ArchiveLimits no_ratio;
  no_ratio.max_ratio = 1 << 20;
  no_ratio.max_file_bytes = 64 << 20;
  EXPECT_THAT(Refusal(honest_bomb, no_ratio), HasSubstr("1073741824 bytes, over the limit of 67108864"));
  EXPECT_THAT(Refusal(overlap_bomb), HasSubstr("member 2 'c/b.csv': overlaps member 1 'c/a'"));
  EXPECT_LT(PeakRss(), peak_before + (64u << 20)) << "the bombs allocated what they claimed";
}

// Issue 15, item 6: 250 members of 1 MiB each (none over the per-member floor of the ratio rule)
// passed in a 638 KB zip and unpacked to 262 MB. The ratio now holds for the archive as a whole.
TEST(ReadZip, TheRatioRuleHoldsForTheWholeArchive) {
  constexpr size_t kMembers = 250;
  const std::string zeros = DeflatedZeros(1);  // 1 MiB of zeros, ~1 KB deflated
  std::vector<ZipEntry> entries;
  for (size_t i = 0; i < kMembers; ++i) {
    ZipEntry e("c/rec_" + std::to_string(i) + ".csv", "");
    e.packed = zeros;
    e.size = 1u << 20;
    e.crc = zip_writer::Crc(std::string(1u << 20, '\0'));
    entries.push_back(std::move(e));
  }
  const std::string archive = Zip(entries);
  const uint64_t peak_before = PeakRss();
  EXPECT_THAT(Refusal(archive), HasSubstr("the members inflate to " + std::to_string(kMembers << 20) +
                                          " bytes, over 100 times the archive's " + std::to_string(archive.size())));
  EXPECT_LT(PeakRss(), peak_before + (64u << 20)) << "the members were inflated before the refusal";
  // A campaign's CSVs deflate a few times at most: far inside the rule.
  std::string csv;
  for (int i = 0; i < 40000; ++i) csv += std::to_string(i * 1e-5) + "," + std::to_string(0.1 * (i % 97)) + "\n";
  EXPECT_EQ(Refusal(Zip({{"c/manifest.json", "{}"}, {"c/rec.csv", csv}})), "");
}

}  // namespace
}  // namespace strokelab::server
