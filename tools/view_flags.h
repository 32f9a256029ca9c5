#pragma once

// The live web view's flags (docs/view.md), shared by the commands that run
// the engine (batch, demo, live) and by `flysfm view`.

#include <memory>

#include <CLI/CLI.hpp>

#include "io/view/view_server.h"

namespace flysfm {

struct ViewFlags {
  // -1: no view. `--view` alone serves on kDefaultViewPort; `--view=0` on
  // any free port (the address is printed).
  int port = -1;
  bool lan = false;

  static constexpr int kDefaultViewPort = 8090;
};

// `--view [PORT]` and `--view-lan` on `command`.
void AddViewFlags(CLI::App* command, ViewFlags* flags);

// The server the flags ask for, its address printed (with the token on the
// LAN); null when no view was asked for. Throws std::runtime_error when it
// cannot start (a port in use, libjs-three missing).
std::unique_ptr<ViewServer> StartView(const ViewFlags& flags);

// Returns after SIGINT or SIGTERM (Ctrl-C), for a view that outlives its run.
void WaitForInterrupt();

}  // namespace flysfm
