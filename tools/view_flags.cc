#include "tools/view_flags.h"

#include <signal.h>
#include <unistd.h>

#include <cstdio>

namespace flysfm {
namespace {

volatile sig_atomic_t interrupted = 0;

void OnInterrupt(int) { interrupted = 1; }

}  // namespace

void AddViewFlags(CLI::App* command, ViewFlags* flags) {
  // expected(0, 1): `--view` alone takes the default string as its value.
  command
      ->add_option("--view", flags->port,
                   "Serve a live 3D view of the model in the browser on this port (8090 "
                   "when given alone; 0: any free port); the address is printed. Give the "
                   "port as --view=PORT before a positional argument")
      ->expected(0, 1)
      ->default_str(std::to_string(ViewFlags::kDefaultViewPort))
      ->check(CLI::Range(0, 65535));
  command->add_flag("--view-lan", flags->lan,
                    "Serve the view on every network interface (a tablet on the same WiFi), "
                    "protected by a random token printed at start");
}

std::unique_ptr<ViewServer> StartView(const ViewFlags& flags) {
  if (flags.port < 0) {
    if (flags.lan) std::fprintf(stderr, "--view-lan has no effect without --view\n");
    return nullptr;
  }
  ViewServerOptions options;
  options.port = flags.port;
  options.lan = flags.lan;
  auto server = std::make_unique<ViewServer>(options);
  std::printf("view: %s%s\n", server->Url().c_str(),
              flags.lan ? "  (anyone with this token can watch; the page keeps it)" : "");
  std::fflush(stdout);
  return server;
}

void WaitForInterrupt() {
  struct sigaction action {};
  action.sa_handler = OnInterrupt;
  sigemptyset(&action.sa_mask);
  ::sigaction(SIGINT, &action, nullptr);
  ::sigaction(SIGTERM, &action, nullptr);
  // A thread that blocked them (the live command's signal thread) still
  // takes them; here they only need to end a wait.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_UNBLOCK, &signals, nullptr);
  while (!interrupted) ::usleep(100 * 1000);
}

}  // namespace flysfm
