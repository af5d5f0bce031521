// A small tmpfs for a test, mounted in a mount namespace of its own (unshare -rm: no privileges
// needed where unprivileged user namespaces are allowed) and kept alive by a holder process.
// Programs run in it through Wrapper() (nsenter); the test reaches its files through
// /proc/HOLDER/root (Path()); Resize() gives it more room (or less) while programs use it.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "process/child.h"

namespace strokelab::test_fault {

using namespace strokelab::test_process;

class SmallTmpfs {
 public:
  // Mounts a tmpfs of `bytes` on `mount_point` (created) in a new namespace; Ok() says whether it
  // worked, Why() why not.
  SmallTmpfs(const fs::path& mount_point, size_t bytes) : mount_point_(mount_point) {
    fs::create_directories(mount_point);
    holder_ = std::make_unique<Child>(
        std::vector<std::string>{"/usr/bin/unshare", "-rm", "sh", "-c",
                                 "mount -t tmpfs -o size=" + std::to_string(bytes) + " strokelab-fault '" +
                                     mount_point.string() + "' && echo mounted && exec sleep 600"},
        mount_point.parent_path() / "tmpfs-holder.log");
    const auto start = Clock::now();
    while (holder_->Out().find("mounted") == std::string::npos) {
      if (holder_->Poll() || SecondsSince(start) > 10) {
        why_ = "cannot mount a tmpfs in a user namespace: " + holder_->Log();
        return;
      }
      SleepMs(5);
    }
    ok_ = true;
  }
  bool Ok() const { return ok_; }
  const std::string& Why() const { return why_; }

  // argv prefix that runs a program in the namespace that sees the tmpfs.
  std::vector<std::string> Wrapper() const {
    return {"/usr/bin/nsenter", "--preserve-credentials", "-U", "-m", "-t", std::to_string(holder_->pid()), "--"};
  }
  // A path under the mount point as this process can reach it.
  fs::path Path(const fs::path& under_mount_point) const {
    return fs::path("/proc/" + std::to_string(holder_->pid()) + "/root") / mount_point_.relative_path() /
           under_mount_point;
  }
  // The mount point as programs run through Wrapper() see it.
  const fs::path& MountPoint() const { return mount_point_; }

  void Resize(size_t bytes) {
    std::vector<std::string> argv = Wrapper();
    argv.insert(argv.end(), {"/bin/mount", "-o", "remount,size=" + std::to_string(bytes), mount_point_.string()});
    Child mount(argv, mount_point_.parent_path() / "tmpfs-resize.log");
    if (mount.WaitExit(10) != 0) throw std::runtime_error("cannot resize the tmpfs: " + mount.Log());
  }

 private:
  fs::path mount_point_;
  std::unique_ptr<Child> holder_;  // killed (and the tmpfs gone with its namespace) at the end
  bool ok_ = false;
  std::string why_;
};

}  // namespace strokelab::test_fault
