// `flysfm camfi-emulator --images DIR`: a stand-in for a CAMFI transmitter on
// 127.0.0.1, to try `flysfm live --camfi` without the hardware (and to test
// it against the faults of a real link).

#include <pthread.h>
#include <signal.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include "io/camfi/camfi_emulator.h"
#include "io/sources/image_source.h"
#include "tools/commands.h"

namespace flysfm {

void AddCamfiEmulatorCommand(CLI::App& app) {
  struct Flags {
    std::string images;
    CamfiEmulatorOptions options;
    std::vector<std::string> faults;
    int max_images = 0;
    std::string request_log;
  };
  auto flags = std::make_shared<Flags>();
  CLI::App* command = app.add_subcommand(
      "camfi-emulator",
      "Stand in for a CAMFI WiFi transmitter on 127.0.0.1: shoots a folder of images "
      "one by one onto a fake card, announces each with file_added, serves the REST "
      "routes; for `flysfm live --camfi 127.0.0.1:PORT`");
  CamfiEmulatorOptions& o = flags->options;
  command->add_option("--images", flags->images,
                      "Image folder or TUM sequence folder; shot in name / rgb.txt order "
                      "(non-JPEG files are re-encoded as JPEG)")
      ->required();
  command->add_option("--port-http", o.http_port, "REST port (0: any free port)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  command->add_option("--port-events", o.event_port, "Socket.IO port (0: any free port)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  command->add_option("--interval", o.interval_seconds,
                      "Seconds between shots, from the first client's connection")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  std::ostringstream fault_help;
  fault_help << "Comma-separated faults:";
  for (const std::string& name : CamfiFaultNames()) fault_help << " " << name;
  command->add_option("--faults", flags->faults, fault_help.str() + "; default: none")
      ->delimiter(',');
  command->add_option("--fault-every", o.fault_every,
                      "A per-shot fault hits every N-th shot (offset drawn from --seed)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--seed", o.seed, "Seed of the fault offsets")->capture_default_str();
  command->add_option("--password", o.password,
                      "Password the `auth` fault asks for (user CamFi)")
      ->capture_default_str();
  command->add_option("--engine-io", o.engine_io_version,
                      "Engine.IO protocol: 3 (socket.io 1.x/2.x) or 4 (server pings)")
      ->check(CLI::IsMember({3, 4}))
      ->capture_default_str();
  command->add_option("--ping-interval-ms", o.ping_interval_ms,
                      "pingInterval of the Engine.IO open packet")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--ping-timeout-ms", o.ping_timeout_ms,
                      "pingTimeout of the Engine.IO open packet")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--max-images", flags->max_images,
                      "Shoot only the first N images (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--request-log", flags->request_log,
                      "Write every HTTP request line (target as received) here on exit");
  command->callback([flags]() {
    int exit_code = 0;
    try {
      CamfiEmulatorOptions options = flags->options;
      for (const std::string& name : flags->faults) {
        const std::optional<CamfiFault> fault = ParseCamfiFault(name);
        if (!fault) throw std::invalid_argument("unknown fault '" + name + "'");
        options.faults.insert(*fault);
      }
      std::vector<Frame> frames = ListBatchInput(flags->images);
      if (flags->max_images > 0 && int(frames.size()) > flags->max_images) {
        frames.resize(std::size_t(flags->max_images));
      }
      for (const Frame& frame : frames) options.images.push_back(frame.path);
      // Blocked before the emulator's threads start, so that sigwait below
      // is the one place the signals arrive.
      sigset_t signals;
      sigemptyset(&signals);
      sigaddset(&signals, SIGINT);
      sigaddset(&signals, SIGTERM);
      pthread_sigmask(SIG_BLOCK, &signals, nullptr);
      CamfiEmulator emulator(options);
      std::printf("CAMFI emulator: REST on http://127.0.0.1:%d, events on 127.0.0.1:%d; "
                  "%d images, one every %g s once a client connects. Try:\n"
                  "  flysfm live --camfi 127.0.0.1:%d --camfi-events-port %d --out live_out\n",
                  emulator.http_port(), emulator.event_port(), emulator.num_images(),
                  options.interval_seconds, emulator.http_port(), emulator.event_port());
      std::fflush(stdout);
      int signal = 0;
      sigwait(&signals, &signal);
      const CamfiEmulatorStats stats = emulator.stats();
      std::printf(
          "CAMFI emulator: %d shots, %d events sent, %d downloads served; faults: "
          "%d sockets dropped, %d stalled, %d events duplicated, %d missing, %d "
          "reordered, %d bodies truncated, %d trickled, %d HTTP 500, %d unauthorised\n",
          stats.shots, stats.events_sent, stats.raw_served, stats.sockets_dropped,
          stats.sockets_stalled, stats.events_duplicated, stats.events_missing,
          stats.events_reordered, stats.bodies_truncated, stats.bodies_trickled, stats.http_500,
          stats.unauthorized);
      if (!flags->request_log.empty()) {
        std::ofstream log(flags->request_log);
        for (const std::string& line : emulator.RequestLog()) log << line << "\n";
      }
    } catch (const std::invalid_argument& e) {
      std::cerr << "flysfm camfi-emulator: " << e.what() << "\n";
      exit_code = 2;
    } catch (const std::runtime_error& e) {
      std::cerr << "flysfm camfi-emulator: " << e.what() << "\n";
      exit_code = 1;
    }
    if (exit_code != 0) throw CLI::RuntimeError(exit_code);
  });
}

}  // namespace flysfm
