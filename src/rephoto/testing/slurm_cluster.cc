#include "rephoto/testing/slurm_cluster.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "rephoto/testing/testing.h"

namespace rephoto::testing {

namespace fs = std::filesystem;

namespace {

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  std::string out = text.str();
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

std::string Quote(const std::string& text) {
  std::string word = "'";
  for (char c : text) word += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return word + "'";
}

int RunScript(const std::string& action, const fs::path& dir, const std::string& extra = "") {
  const std::string command = "bash " + Quote((SourceDir() / "scripts/slurm-cluster.sh").string()) +
                              " " + action + " " + extra + " " + Quote(dir.string());
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

// The cluster this process started itself (no ctest fixture), stopped at exit.
struct OwnCluster {
  fs::path dir;
  ~OwnCluster() {
    if (dir.empty()) return;
    RunScript("stop", dir);
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

SlurmAvailability Use(const fs::path& dir, SlurmCluster* cluster, std::string* why) {
  cluster->dir = dir;
  cluster->conf = dir / "slurm.conf";
  cluster->node = ReadText(dir / "node");
  if (RunScript("status", dir) != 0) {
    *why = "the Slurm test cluster in " + dir.string() + " does not answer; see " +
           (dir / "log").string();
    return SlurmAvailability::kBroken;
  }
  ::setenv("SLURM_CONF", cluster->conf.c_str(), 1);
  return SlurmAvailability::kRunning;
}

}  // namespace

SlurmAvailability RequireSlurmCluster(SlurmCluster* cluster, std::string* why) {
  const char* fixture = std::getenv("REPHOTO_TEST_SLURM_DIR");
  if (fixture != nullptr && *fixture != '\0') {
    const fs::path dir = fixture;
    if (fs::exists(dir / "skipped")) {
      *why = ReadText(dir / "skipped");
      return SlurmAvailability::kSkipped;
    }
    if (!fs::exists(dir / "slurm.conf")) {
      *why = "REPHOTO_TEST_SLURM_DIR=" + dir.string() +
             " holds no cluster (did the fixture test cluster/slurm_start run?)";
      return SlurmAvailability::kBroken;
    }
    return Use(dir, cluster, why);
  }
  static OwnCluster own;
  static std::string own_skip;
  if (!own_skip.empty()) {
    *why = own_skip;
    return SlurmAvailability::kSkipped;
  }
  if (own.dir.empty()) {
    // Short: the munge socket's path must fit a sockaddr_un (108 bytes).
    char pattern[] = "/tmp/rephoto-slurm-XXXXXX";
    if (::mkdtemp(pattern) == nullptr) {
      *why = "cannot create a folder in /tmp for the Slurm test cluster";
      return SlurmAvailability::kBroken;
    }
    const fs::path dir = pattern;
    const int code = RunScript("start", dir, "--skip-code 77");
    if (code == 77) {
      own_skip = ReadText(dir / "skipped");
      std::error_code ec;
      fs::remove_all(dir, ec);
      *why = own_skip;
      return SlurmAvailability::kSkipped;
    }
    own.dir = dir;  // stopped at exit even when it started only half-way
    if (code != 0) {
      *why = "scripts/slurm-cluster.sh start failed; see " + (dir / "log").string();
      return SlurmAvailability::kBroken;
    }
  }
  return Use(own.dir, cluster, why);
}

}  // namespace rephoto::testing
