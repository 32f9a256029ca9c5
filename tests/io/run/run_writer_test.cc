#include "io/run/run_writer.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "core/engine.h"
#include "io/formats/colmap_model.h"
#include "io/synthetic/synthetic_source.h"
#include "tests/testing/skip.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/rendered_capture.h"
#include "tests/testing/scene_reconstruction.h"

namespace flysfm {
namespace {

namespace fs = std::filesystem;

// A real run: the engine on a small rendered capture, finished, written.
struct WrittenRun {
  Reconstruction model;
  fs::path dir;
};

const WrittenRun& Written() {
  static const WrittenRun run = [] {
    SyntheticCaptureOptions options;
    options.num_views = 8;
    options.path_length = 1.5;
    const SyntheticCapture capture = testing::RenderedCapture(options);
    Engine engine(Engine::Options(), capture.camera);
    std::vector<ImageResult> results;
    for (const Frame& frame : capture.frames) {
      for (const ImageResult& result : engine.AddImage(frame)) results.push_back(result);
    }
    engine.Finish();
    WrittenRun written{engine.reconstruction(), testing::MakeTempDir("run_writer_test")};
    RunWriter writer(written.dir);
    for (const ImageResult& result : results) writer.Log(result);
    REQUIRE(writer.MayReplaceOutputs(written.model, /*final=*/false));
    writer.WriteModel(written.model);
    RunCounts counts;
    counts.images_in = int(capture.frames.size());
    writer.WriteSummary(written.model, results, counts, engine.PendingImageNames(), 1.0);
    return written;
  }();
  return run;
}

void CheckSameModel(const Reconstruction& read, const Reconstruction& model) {
  CHECK(read.NumRegisteredImages() == model.NumRegisteredImages());
  CHECK(read.NumPoints3D() == model.NumPoints3D());
  CHECK(read.NumObservations() == model.NumObservations());
  for (const image_t id : model.RegisteredImageIds()) {
    const Image& image = model.image(id);
    const Rigid3d& pose = *image.cam_from_world;
    const Rigid3d& read_pose = *read.image(id).cam_from_world;
    CHECK(read.image(id).name == image.name);
    CHECK(read_pose.rotation.angularDistance(pose.rotation) < 1e-12);
    CHECK((read_pose.translation - pose.translation).norm() < 1e-12);
  }
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

double MeanPointError(const Reconstruction& model) {
  double sum = 0;
  for (const auto& [id, point] : model.points3D()) sum += point.error;
  return sum / double(model.NumPoints3D());
}

// "Label: value" lines of `colmap model_analyzer` (glog prefixes stripped).
std::map<std::string, double> AnalyzeWithColmap(const fs::path& model_dir) {
  const fs::path log = model_dir.parent_path() / (model_dir.filename().string() + ".analyzer");
  const std::string command =
      "colmap model_analyzer --path '" + model_dir.string() + "' > '" + log.string() + "' 2>&1";
  REQUIRE(std::system(command.c_str()) == 0);
  std::map<std::string, double> figures;
  std::ifstream in(log);
  for (std::string line; std::getline(in, line);) {
    const std::size_t bracket = line.find("] ");
    if (bracket != std::string::npos) line = line.substr(bracket + 2);
    const std::size_t colon = line.find(": ");
    if (colon == std::string::npos) continue;
    std::istringstream value(line.substr(colon + 2));
    double number;
    if (value >> number) figures[line.substr(0, colon)] = number;
  }
  return figures;
}

TEST_CASE("A log line names the focal length the initial pairs corrected, only when they did") {
  ImageResult result;
  result.name = "IMG_0002.JPG";
  CHECK_FALSE(ToJson(result).contains("focal_length_from_pairs"));
  result.focal_length_from_pairs = 2736.5;
  CHECK(ToJson(result)["focal_length_from_pairs"].get<double>() == 2736.5);
}

TEST_CASE("A log record names its source, the summary counts each source") {
  const fs::path dir = testing::MakeTempDir("run_writer_sources");
  {
    RunWriter writer(dir);
    ImageResult result;
    result.name = "alice/IMG_0001.JPG";
    result.status = ImageStatus::kRejected;
    writer.Log(result, "alice");
    result.name = "IMG_0002.JPG";
    writer.Log(result);
    RunCounts counts;
    counts.images_in = 2;
    counts.sources = {{"alice", 2, 0, 1, 1}, {"bob", 0, 0, 0, 0}};
    writer.WriteSummary(Reconstruction(), {result, result}, counts, {"alice/IMG_0003.JPG"}, 1.0);
  }
  std::ifstream log(dir / "log.jsonl");
  std::string first, second;
  std::getline(log, first);
  std::getline(log, second);
  CHECK(nlohmann::json::parse(first)["source"] == "alice");
  CHECK_FALSE(nlohmann::json::parse(second).contains("source"));
  std::ifstream summary(dir / "summary.json");
  const nlohmann::json json = nlohmann::json::parse(summary);
  REQUIRE(json["sources"].size() == 2);
  CHECK(json["sources"][0] ==
        nlohmann::json({{"tag", "alice"}, {"images_in", 2}, {"registered", 0}, {"rejected", 1},
                        {"pending", 1}}));
  CHECK(json["sources"][1]["tag"] == "bob");
  // A single source's summary has no "sources".
  RunWriter(dir).WriteSummary(Reconstruction(), {}, RunCounts(), {}, 1.0);
  std::ifstream single(dir / "summary.json");
  CHECK_FALSE(nlohmann::json::parse(single).contains("sources"));
}

TEST_CASE("With a quality tracker: ms.quality in the log, the measures in summary and PLY") {
  const Reconstruction& model = Written().model;
  QualityTracker quality;
  quality.Rebuild(model);
  const fs::path dir = testing::MakeTempDir("run_writer_quality");
  {
    RunWriter writer(dir);
    ImageResult result;
    result.name = "IMG_0001.JPG";
    result.times.ba = 2;
    result.times.UpdateTotal();
    writer.Log(result, "", 1.5);
    writer.Log(result);
    writer.WriteModel(model, &quality);
    writer.WriteSummary(model, {result}, RunCounts(), {}, 1.0, &quality);
  }
  std::ifstream log(dir / "log.jsonl");
  std::string first, second;
  std::getline(log, first);
  std::getline(log, second);
  const nlohmann::json record = nlohmann::json::parse(first);
  CHECK(record["ms"]["quality"] == 1.5);
  CHECK(record["ms"]["total"] == 2);  // the engine's stages alone
  CHECK_FALSE(nlohmann::json::parse(second)["ms"].contains("quality"));

  std::ifstream summary_file(dir / "summary.json");
  const nlohmann::json json = nlohmann::json::parse(summary_file)["quality"];
  CHECK(json["points"] == model.NumPoints3D());
  CHECK(json["images"] == model.NumRegisteredImages());
  CHECK(json["sigma_px"] == Approx(quality.SigmaPx()));
  CHECK(json["sigma_source"] == SigmaSourceName(quality.options().sigma_source));
  CHECK(json["min_views"] == 3);
  REQUIRE(json["per_image"].size() == model.NumRegisteredImages());
  const nlohmann::json& first_image = json["per_image"][0];
  const image_t first_id = *std::min_element(model.RegisteredImageIds().begin(),
                                             model.RegisteredImageIds().end());
  CHECK(first_image["name"] == model.image(first_id).name);
  CHECK(first_image["inliers"] == model.image(first_id).num_points3D);
  CHECK(first_image["spread"].get<double>() > 0);
  CHECK(first_image["spread"].get<double>() <= 1);

  std::ifstream ply(dir / "points.ply", std::ios::binary);
  std::string line, header;
  while (std::getline(ply, line) && line != "end_header") header += line + "\n";
  CHECK(header.find("property float sigma") != std::string::npos);
  // 3 doubles, 3 uchars, an int and 3 floats per vertex.
  const auto body = ply.tellg();
  ply.seekg(0, std::ios::end);
  CHECK(std::size_t(ply.tellg() - body) == model.NumPoints3D() * (24 + 3 + 4 + 12));
}

TEST_CASE("With coverage: ms.coverage in the log, the surface in summary.json and surface.ply") {
  const Reconstruction& model = Written().model;
  Coverage coverage;
  coverage.Update(model);
  REQUIRE(coverage.summary().faces > 0);
  const fs::path dir = testing::MakeTempDir("run_writer_coverage");
  {
    RunWriter writer(dir);
    ImageResult result;
    result.name = "IMG_0001.JPG";
    writer.Log(result, "", 1.5, 7.0);
    writer.WriteModel(model, nullptr, &coverage);
    writer.WriteSummary(model, {result}, RunCounts(), {}, 1.0, nullptr, &coverage);
  }
  std::ifstream log(dir / "log.jsonl");
  std::string first;
  std::getline(log, first);
  CHECK(nlohmann::json::parse(first)["ms"]["coverage"] == 7.0);

  std::ifstream summary_file(dir / "summary.json");
  const nlohmann::json json = nlohmann::json::parse(summary_file)["coverage"];
  CHECK(json["faces"] == coverage.summary().faces);
  CHECK(json["well_covered_share"] == coverage.summary().well_covered_share);
  CHECK(json["min_views"] == coverage.options().min_views);
  REQUIRE(json["suggestions"].size() == coverage.suggestions().size());
  for (std::size_t i = 0; i < coverage.suggestions().size(); ++i) {
    CHECK(json["suggestions"][i]["reason"] == coverage.suggestions()[i].reason);
    CHECK(json["suggestions"][i]["position"][0] == coverage.suggestions()[i].position.x());
  }

  std::ifstream ply(dir / "surface.ply", std::ios::binary);
  std::string line, header;
  while (std::getline(ply, line) && line != "end_header") header += line + "\n";
  CHECK(header.find("element face " + std::to_string(coverage.faces().size())) !=
        std::string::npos);
  // Per face three float vertices, then its record: a count, three int
  // indices, three colour bytes, an int, two floats and a class byte.
  const auto body = ply.tellg();
  ply.seekg(0, std::ios::end);
  CHECK(std::size_t(ply.tellg() - body) == coverage.faces().size() * (36 + 1 + 12 + 3 + 4 + 8 + 1));
}

TEST_CASE("The run's sparse/ model reads back, text and binary, as the engine's model") {
  const WrittenRun& run = Written();
  REQUIRE(run.model.NumRegisteredImages() >= 6);
  CheckSameModel(ReadColmapText(run.dir / "sparse"), run.model);
  CheckSameModel(ReadColmapBinary(run.dir / "sparse"), run.model);
  for (const char* file : {"points.ply", "trajectory.txt", "log.jsonl", "summary.json"}) {
    CHECK(fs::file_size(run.dir / file) > 0);
  }
  std::ifstream summary(run.dir / "summary.json");
  const nlohmann::json json = nlohmann::json::parse(summary);
  CHECK(json["images_in"].get<int>() == 8);
  CHECK(json["registered"].get<std::size_t>() == run.model.NumRegisteredImages());
  REQUIRE(json["cameras"].size() == run.model.cameras().size());
  const Camera& camera = run.model.cameras().begin()->second;
  CHECK(json["cameras"][0]["params"].get<std::vector<double>>() == camera.params);
  CHECK(json["cameras"][0]["readout_time_s"].get<double>() == camera.readout_time);
}

TEST_CASE("Each sub-model is written apart: the largest in sparse/, the others beside it") {
  testing::SyntheticSceneOptions options;
  options.num_images = 10;
  options.num_points = 300;
  const Sim3d second_from_world(2, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())),
                                Eigen::Vector3d(1, 2, 3));
  testing::TwoSubModelScene two =
      testing::TwoSubModelsFromScene(testing::MakeSyntheticScene(options), 4, second_from_world);
  Reconstruction& model = two.reconstruction;
  const fs::path dir = testing::MakeTempDir("run_writer_sub_models");
  RunWriter writer(dir);
  REQUIRE(writer.MayReplaceOutputs(model, /*final=*/false));
  writer.WriteModel(model);
  writer.WriteSummary(model, {}, RunCounts(), {}, 1.0);
  // Six images in the second, four in the first.
  CheckSameModel(ReadColmapText(dir / "sparse"), model.SubModel(two.second_id));
  CheckSameModel(ReadColmapBinary(dir / "sparse" / "1"),
                 model.SubModel(Reconstruction::kFirstModelId));
  CHECK_FALSE(fs::exists(dir / "sparse" / "2"));
  std::ifstream summary_file(dir / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(summary_file);
  REQUIRE(summary["models"].size() == 2);
  CHECK(summary["models"][0]["id"] == two.second_id);
  CHECK(summary["models"][0]["images"] == 6);
  CHECK(summary["models"][1]["images"] == 4);
  CHECK(summary["models"][0]["points"].get<std::size_t>() +
            summary["models"][1]["points"].get<std::size_t>() ==
        model.NumPoints3D());

  // Merged, one model: sparse/1 goes.
  model.MergeModels(Reconstruction::kFirstModelId, two.second_id, second_from_world);
  writer.WriteModel(model);
  CheckSameModel(ReadColmapText(dir / "sparse"), model);
  CHECK_FALSE(fs::exists(dir / "sparse" / "1"));
}

TEST_CASE("A restart keeps the previous model until it has as many images, and the log") {
  const WrittenRun& run = Written();
  const fs::path dir = testing::MakeTempDir("run_writer_restart");
  fs::copy(run.dir, dir, fs::copy_options::recursive);
  const std::string log_before = ReadText(dir / "log.jsonl");
  const std::string summary_before = ReadText(dir / "summary.json");
  const std::string images_before = ReadText(dir / "sparse" / "images.txt");

  // The restart's model so far: the first images of the same session.
  Reconstruction smaller = run.model;
  const std::vector<image_t> registered = smaller.RegisteredImageIds();
  for (std::size_t i = 2; i < registered.size(); ++i) smaller.DeRegisterImage(registered[i]);
  REQUIRE(smaller.NumRegisteredImages() == 2);
  RunWriter restart(dir);
  ImageResult result;
  result.name = "restart";
  restart.Log(result);
  CHECK_FALSE(restart.MayReplaceOutputs(smaller, /*final=*/false));
  CHECK(ReadText(dir / "sparse" / "images.txt") == images_before);
  CHECK(ReadText(dir / "summary.json") == summary_before);
  // The log goes on from where the previous run left it.
  CHECK(ReadText(dir / "log.jsonl") == log_before + ToJson(result).dump() + "\n");

  // As large again: replaced from then on.
  CHECK(restart.MayReplaceOutputs(run.model, /*final=*/false));
  CHECK(restart.MayReplaceOutputs(smaller, /*final=*/false));

  // A run that ends smaller writes its own, the previous ones moved aside.
  RunWriter shorter(dir);
  CHECK(shorter.MayReplaceOutputs(smaller, /*final=*/true));
  CHECK(ReadText(dir / "previous" / "summary.json") == summary_before);
  CHECK(ReadText(dir / "previous" / "sparse" / "images.txt") == images_before);
}

TEST_CASE("colmap model_analyzer reads the run's sparse/ model, binary and text") {
  if (std::system("command -v colmap > /dev/null 2>&1") != 0) {
    testing::SkipTest("colmap is not installed (scripts/setup.sh installs it)");
  }
  const WrittenRun& run = Written();
  // sparse/ holds both formats; COLMAP reads the .bin files when present, so
  // the text files are checked on their own in a copy.
  const fs::path text_dir = run.dir / "sparse_text";
  fs::create_directories(text_dir);
  for (const char* file : {"cameras.txt", "images.txt", "points3D.txt"}) {
    fs::copy_file(run.dir / "sparse" / file, text_dir / file, fs::copy_options::overwrite_existing);
  }
  for (const fs::path& dir : {run.dir / "sparse", text_dir}) {
    INFO(dir);
    const std::map<std::string, double> figures = AnalyzeWithColmap(dir);
    REQUIRE(figures.count("Registered images"));
    CHECK(figures.at("Cameras") == double(run.model.cameras().size()));
    CHECK(figures.at("Registered images") == double(run.model.NumRegisteredImages()));
    CHECK(figures.at("Points") == double(run.model.NumPoints3D()));
    CHECK(figures.at("Observations") == double(run.model.NumObservations()));
    // COLMAP's figure is the mean of the points' stored track errors.
    CHECK(figures.at("Mean reprojection error") == Approx(MeanPointError(run.model)).margin(1e-3));
  }
}

}  // namespace
}  // namespace flysfm
