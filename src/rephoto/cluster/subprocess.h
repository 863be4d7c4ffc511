// Running Slurm's client programs (sbatch, squeue, scancel, sacct, scontrol) and capturing
// their output.
//
// The program runs in a process group of its own, so a Ctrl-C meant for rephoto (SIGINT to the
// terminal's foreground group) does not kill an `sbatch` half-way through a submission; stdin is
// /dev/null. Thread safety: reentrant (no shared state).
#pragma once

#include <string>
#include <vector>

namespace rephoto::cluster {

struct ProgramOutput {
  int exit_code = 0;  // the program's exit status; 127 when it could not be executed
  int signal = 0;     // terminating signal, 0 when it exited
  std::string out;    // everything it wrote to stdout
  std::string err;    // everything it wrote to stderr
  bool ok() const { return exit_code == 0 && signal == 0; }
  // The first non-empty line of stderr (or stdout), trimmed, for one-line messages.
  std::string FirstLine() const;
};

// Runs argv[0] (looked up on PATH when it has no '/') with the arguments argv[1..] and waits
// for it. Throws Error "<argv[0]>: cannot start: <reason>" when it cannot be started (not
// found, not executable); a program that starts and fails is an ordinary ProgramOutput.
ProgramOutput RunProgram(const std::vector<std::string>& argv);

}  // namespace rephoto::cluster
