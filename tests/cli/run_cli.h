// Runs the strokelab binary with arguments and captures exit code, stdout and stderr.
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <string>

namespace strokelab::testing {

struct CliResult {
  int exit_code = -1;
  std::string stdout_text, stderr_text;
};

inline CliResult RunCli(const std::string& args) {
  // One stderr file per process and call: CTest runs test processes side by side.
  static int calls = 0;
  const std::string err_path = ::testing::TempDir() + "/strokelab_cli_stderr_" + std::to_string(::getpid()) + "_" +
                               std::to_string(++calls) + ".txt";
  const std::string command = std::string(STROKELAB_BINARY) + " " + args + " 2>" + err_path;
  CliResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) result.stdout_text.append(buffer.data(), n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::ifstream err(err_path);
  result.stderr_text.assign(std::istreambuf_iterator<char>(err), {});
  std::remove(err_path.c_str());
  return result;
}

// `strokelab ARGS` fails with one line on stderr, exit code 2 and nothing on stdout, and the line
// holds `expected` (the field and what is wrong with it).
inline void ExpectInputError(const std::string& args, const std::string& expected) {
  const CliResult r = RunCli(args);
  EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.stderr_text;
  EXPECT_THAT(r.stderr_text, ::testing::HasSubstr(expected)) << args;
  EXPECT_EQ(std::count(r.stderr_text.begin(), r.stderr_text.end(), '\n'), 1) << r.stderr_text;
  EXPECT_TRUE(r.stdout_text.empty()) << r.stdout_text;
}

}  // namespace strokelab::testing
