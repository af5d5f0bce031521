// The SQLite schema migrations of schema/migrations/, compiled into the binary
// (server/cmake/embed_migrations.cmake generates the definition). Internal to the store.
#pragma once

#include <span>

namespace strokelab::server::internal {

struct Migration {
  int version;       // 1, 2, 3, ...: the database's PRAGMA user_version after applying it
  const char* name;  // file name, e.g. "001_initial.sql"
  const char* sql;   // the whole file
};

// In version order, without gaps.
std::span<const Migration> Migrations();

}  // namespace strokelab::server::internal
