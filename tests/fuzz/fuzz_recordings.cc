// libFuzzer harness: a campaign directory read by ReadCampaign (clients/recordings).
//
// The input is split at the byte 0x1E (ASCII record separator): the first part is written as
// manifest.json, the following parts as rec_001.csv, rec_002.csv, ... in a directory that is emptied
// before each input. The seed corpus (corpus/recordings) holds valid cuts of campaign-a in this
// form, so mutations start from manifests that name those files. A first part that names the
// format "strokelab-mapping/1" is written as mapping.json instead (a campaign of UFF 58 or WAV files,
// data/include/strokelab/data/mapping.h), and its parts as rec_001.uff, ... or, for a part that
// starts with "RIFF", rec_001.wav, ... (the uff_* and wav_* seeds).
//
// The contract checked (recordings.h): a bad campaign throws strokelab::InputError and nothing else;
// any other exception escapes and libFuzzer reports it as a crash.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "fuzz_temp_dir.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/recordings.h"

namespace {

namespace fs = std::filesystem;

constexpr char kSeparator = '\x1e';

void WriteFile(const fs::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const fs::path dir = strokelab::fuzz::ProcessTempDir() / "campaign";
  fs::remove_all(dir);
  fs::create_directories(dir);

  std::string_view rest(reinterpret_cast<const char*>(data), size);
  bool mapped = false;
  for (int part = 0;; ++part) {
    const size_t end = rest.find(kSeparator);
    const std::string_view bytes = rest.substr(0, end);
    if (part == 0) mapped = bytes.find(strokelab::kMappingFormat) != std::string_view::npos;
    char name[32];
    std::snprintf(name, sizeof name, "rec_%03d.%s", part,
                  !mapped ? "csv" : (bytes.substr(0, 4) == "RIFF" ? "wav" : "uff"));
    const fs::path first = mapped ? strokelab::kMappingName : strokelab::kManifestName;
    WriteFile(dir / (part == 0 ? first : fs::path(name)), bytes);
    if (end == std::string_view::npos) break;
    rest.remove_prefix(end + 1);
  }

  try {
    (void)strokelab::ReadCampaign(dir);
  } catch (const strokelab::InputError&) {
    // The expected outcome for most inputs.
  }
  return 0;
}
