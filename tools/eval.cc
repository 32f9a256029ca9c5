// `flysfm eval --groundtruth GT --trajectory TRAJ`: TUM's absolute trajectory
// error after Sim3 alignment.

#include <iostream>

#include "io/evaluation/evaluation.h"
#include "tools/commands.h"

namespace flysfm {

void AddEvalCommand(CLI::App& app) {
  struct Flags {
    std::string groundtruth;
    std::string trajectory;
    double max_time_difference = 0.02;
  };
  auto flags = std::make_shared<Flags>();
  CLI::App* command = app.add_subcommand(
      "eval", "Absolute trajectory error (RMSE, median, max) of a TUM-format trajectory "
              "against ground truth, after Sim3 (Umeyama) alignment; last line JSON");
  command->add_option("--groundtruth", flags->groundtruth,
                      "Reference trajectory, TUM format (e.g. groundtruth.txt)")
      ->required();
  command->add_option("--trajectory", flags->trajectory,
                      "Estimated trajectory, TUM format (e.g. OUT/trajectory.txt)")
      ->required();
  command->add_option("--max-time-difference", flags->max_time_difference,
                      "Largest timestamp difference of an associated pair, seconds")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->callback([flags]() {
    int exit_code = 0;
    try {
      const TrajectoryEvaluation evaluation =
          EvaluateTrajectory(ReadTumTrajectory(flags->trajectory),
                             ReadTumTrajectory(flags->groundtruth),
                             flags->max_time_difference);
      std::cout << evaluation.Report();
      if (!evaluation.ate) exit_code = 1;
    } catch (const std::runtime_error& e) {
      std::cerr << "flysfm eval: " << e.what() << "\n";
      exit_code = 2;
    }
    if (exit_code != 0) throw CLI::RuntimeError(exit_code);
  });
}

}  // namespace flysfm
