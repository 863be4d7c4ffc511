#include "rephoto/core/process.h"
#include "rephoto/cluster/subprocess.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <csignal>
#include <cstring>

#include "rephoto/core/error.h"

extern char** environ;

namespace rephoto::cluster {

namespace {

// Closes the descriptors it holds when it goes out of scope.
struct Pipe {
  int fd[2] = {-1, -1};
  ~Pipe() {
    for (int& f : fd) {
      if (f >= 0) ::close(f);
    }
  }
  void CloseEnd(int end) {
    if (fd[end] >= 0) ::close(fd[end]);
    fd[end] = -1;
  }
};

std::string Trim(std::string_view text) {
  const size_t begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string_view::npos) return {};
  const size_t end = text.find_last_not_of(" \t\r\n");
  return std::string(text.substr(begin, end - begin + 1));
}

std::string FirstNonEmptyLine(std::string_view text) {
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string line = Trim(text.substr(start, end - start));
    if (!line.empty()) return line;
    start = end + 1;
  }
  return {};
}

}  // namespace

std::string ProgramOutput::FirstLine() const {
  std::string line = FirstNonEmptyLine(err);
  if (line.empty()) line = FirstNonEmptyLine(out);
  return line;
}

ProgramOutput RunProgram(const std::vector<std::string>& argv) {
  REPHOTO_CHECK(!argv.empty() && !argv[0].empty(), "RunProgram: no program given");
  Pipe out_pipe, err_pipe;
  REPHOTO_CHECK(::pipe2(out_pipe.fd, O_CLOEXEC) == 0 && ::pipe2(err_pipe.fd, O_CLOEXEC) == 0,
                "{}: cannot create a pipe: {}", argv[0], std::strerror(errno));

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, out_pipe.fd[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, err_pipe.fd[1], STDERR_FILENO);
  const ChildSpawnAttributes attributes;

  std::vector<char*> args;
  for (const std::string& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int spawned =
      ::posix_spawnp(&pid, argv[0].c_str(), &actions, attributes.get(), args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  REPHOTO_CHECK(spawned == 0, "{}: cannot start: {}", argv[0], std::strerror(spawned));
  out_pipe.CloseEnd(1);
  err_pipe.CloseEnd(1);

  ProgramOutput result;
  std::array<pollfd, 2> fds = {pollfd{out_pipe.fd[0], POLLIN, 0},
                               pollfd{err_pipe.fd[0], POLLIN, 0}};
  std::array<std::string*, 2> sinks = {&result.out, &result.err};
  int open_count = 2;
  char buffer[65536];
  while (open_count > 0) {
    const int ready = ::poll(fds.data(), fds.size(), -1);
    if (ready < 0) {
      if (errno == EINTR) continue;
      break;
    }
    for (size_t i = 0; i < fds.size(); ++i) {
      if (fds[i].fd < 0 || fds[i].revents == 0) continue;
      const ssize_t n = ::read(fds[i].fd, buffer, sizeof(buffer));
      if (n > 0) {
        sinks[i]->append(buffer, static_cast<size_t>(n));
      } else if (n == 0 || (errno != EINTR && errno != EAGAIN)) {
        fds[i].fd = -1;  // closed by the Pipe destructor
        --open_count;
      }
    }
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      result.exit_code = 127;
      return result;
    }
  }
  if (WIFEXITED(status)) {
    result.exit_code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    result.signal = WTERMSIG(status);
    result.exit_code = 128 + result.signal;
  }
  return result;
}

}  // namespace rephoto::cluster
