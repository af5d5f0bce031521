// The JSON Schema files of schema/*.schema.json as compiled into the binary by
// jobs/cmake/embed_schemas.cmake (a generated source under the build directory).
#pragma once

#include <span>
#include <string_view>

namespace strokelab::jobs::internal {

struct EmbeddedSchema {
  std::string_view name;  // file stem: "job" for schema/job.schema.json
  std::string_view text;  // the file's JSON text
};

std::span<const EmbeddedSchema> EmbeddedSchemas();

}  // namespace strokelab::jobs::internal
