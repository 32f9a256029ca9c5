// The live view in a real browser: `flysfm batch --view` on a rendered scene,
// the page loaded in headless chromium, and what the page shows compared with
// the run's summary.json, its colourings with the run's quality measures.
// Screenshots are kept (the path is printed).

#include <signal.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io/synthetic/synthetic_source.h"
#include "tests/testing/headless_browser.h"
#include "tests/testing/skip.h"
#include "tests/testing/temp_dir.h"
#include "tests/tools/live_process.h"
#include "tests/testing/rendered_capture.h"
#include "tests/testing/sanitizer.h"

namespace flysfm {
namespace {

// Fewer under a sanitizer (tests/testing/sanitizer.h): two wait for the first
// pair, the rest register, and half of them come before a mid-run page.
constexpr int kViews = testing::kSanitizerBuild ? 6 : 8;

std::filesystem::path ArtifactDir() {
  const std::filesystem::path dir = std::filesystem::path(FLYSFM_ARTIFACT_DIR) / "view";
  std::filesystem::create_directories(dir);
  return dir;
}

// A shot of nothing (a lens cap, a grey sky) among the views: it cannot
// register, so the page lists it with its thumbnail.
constexpr const char* kBlankShot = "view102b.png";

// The rendered views as files, like a camera's card, and the blank shot;
// returns the camera.
std::string WriteCapture(const std::filesystem::path& dir) {
  SyntheticCaptureOptions options;
  options.num_views = kViews;
  const SyntheticCapture capture = testing::RenderedCapture(options);
  std::filesystem::create_directories(dir);
  for (const Frame& frame : capture.frames) {
    std::ofstream out(dir / frame.name, std::ios::binary);
    out.write(reinterpret_cast<const char*>(frame.bytes.data()),
              std::streamsize(frame.bytes.size()));
  }
  cv::imwrite((dir / kBlankShot).string(),
              cv::Mat(capture.camera.height, capture.camera.width, CV_8UC3, cv::Scalar::all(128)));
  return capture.camera.ToString();
}

std::filesystem::path Chromium() {
  const std::optional<std::filesystem::path> chromium = testing::FindChromium();
  if (!chromium) {
    testing::SkipTest("no chromium on PATH (Debian package chromium; scripts/setup.sh "
                      "installs it): the browser test of the live view cannot run");
  }
  return *chromium;
}

// The address `flysfm batch --view` printed.
std::string ViewUrl(const std::filesystem::path& output) {
  std::string url;
  REQUIRE(testing::WaitUntil(
      [&] {
        const std::vector<std::string> lines = testing::LinesStartingWith(output, "view: http");
        if (lines.empty()) return false;
        url = lines.front().substr(6);
        url = url.substr(0, url.find(' '));
        return true;
      },
      60));
  return url;
}

nlohmann::json PageState(testing::HeadlessBrowser& browser) {
  return browser.Evaluate(
      "(() => { const v = window.flysfmView; return {cameras: v.cameras, points: v.points, "
      "images: v.images, modelPoints: v.modelPoints, finished: v.finished, errors: v.errors, "
      "updates: v.updates, frameMs: v.frameMs, "
      "imagesText: document.getElementById('images').textContent, "
      "pointsText: document.getElementById('points').textContent}; })()");
}

// Waits for the run's end on the page and compares it with summary.json.
void CheckFinishedPage(testing::HeadlessBrowser& browser, const std::filesystem::path& out,
                       const std::filesystem::path& screenshot) {
  const bool finished = browser.WaitFor("window.flysfmView && window.flysfmView.finished", 300);
  // Kept whatever happens next: what the page showed is the first clue.
  browser.Screenshot(screenshot);
  std::cout << "view_browser_test: screenshot " << screenshot.string() << "\n";
  REQUIRE(finished);
  const nlohmann::json state = PageState(browser);
  const nlohmann::json summary = nlohmann::json::parse(testing::ReadText(out / "summary.json"));
  INFO("page " << state.dump() << "\nsummary " << summary.dump());
  const int registered = summary["registered"].get<int>();
  const int points = summary["points"].get<int>();
  CHECK(registered >= 3);
  CHECK(state["images"] == registered);
  CHECK(state["modelPoints"] == points);
  CHECK(state["imagesText"] == std::to_string(registered));
  CHECK(state["pointsText"] == std::to_string(points));
  CHECK(state["cameras"] == registered);
  CHECK(state["points"] == points);
  CHECK(state["errors"].empty());
  for (const std::string& error : browser.errors()) FAIL_CHECK("browser: " << error);
}

// The blank shot is listed as pending or rejected, with its reason and the
// thumbnail the server kept of it: a loaded grey picture.
void CheckFailedShot(testing::HeadlessBrowser& browser) {
  const nlohmann::json listed = browser.Evaluate(
      "(() => { const items = Array.from(document.querySelectorAll('#pending li, #rejected li'));"
      " return items.map(li => { const img = li.querySelector('img.shot'); return {text: "
      "li.textContent, alt: img ? img.alt : '', width: img ? img.naturalWidth : 0, "
      "complete: img ? img.complete : false}; }); })()");
  INFO("listed " << listed.dump());
  bool found = false;
  for (const nlohmann::json& item : listed) {
    if (item["alt"] != kBlankShot) continue;
    found = true;
    CHECK(item["text"].get<std::string>().find(std::string(kBlankShot) + ": ") == 0);
    CHECK(browser.WaitFor("Array.from(document.querySelectorAll('img.shot')).some(img => img.alt "
                          "=== '" + std::string(kBlankShot) + "' && img.complete && "
                          "img.naturalWidth > 0)", 10));
  }
  CHECK(found);
}

// Chooses a colouring as a user does, in the page's menu.
void ChooseColouring(testing::HeadlessBrowser& browser, const std::string& mode) {
  browser.Evaluate("(() => { const s = document.getElementById('colouring'); s.value = '" + mode +
                   "'; s.dispatchEvent(new Event('change')); return s.value; })()");
}

// The coverage and uncertainty colourings of the finished page: the share of
// well-covered points is summary.json's, the coverage colours count the same
// points, each colouring is drawn, and the points' own colours come back.
void CheckColourings(testing::HeadlessBrowser& browser, const std::filesystem::path& out) {
  const nlohmann::json summary = nlohmann::json::parse(testing::ReadText(out / "summary.json"));
  REQUIRE(summary.contains("quality"));
  const int well_covered = summary["quality"]["well_covered_points"].get<int>();
  const int points = summary["points"].get<int>();
  const nlohmann::json state = browser.Evaluate(
      "(() => { const v = window.flysfmView; return {measured: v.measured, "
      "wellCovered: v.wellCovered, coverage: document.getElementById('coverage').textContent, "
      "colours: v.drawnColours()}; })()");
  INFO("page " << state.dump().substr(0, 400) << "\nsummary " << summary["quality"].dump());
  REQUIRE(state["measured"] == true);
  CHECK(state["wellCovered"] == well_covered);
  CHECK(state["coverage"].get<std::string>().find("Well covered") != std::string::npos);
  const std::vector<int> own = state["colours"].get<std::vector<int>>();
  REQUIRE(own.size() == std::size_t(3 * points));

  ChooseColouring(browser, "coverage");
  browser.Screenshot(ArtifactDir() / "view_coverage.png");
  const std::vector<int> coverage =
      browser.Evaluate("window.flysfmView.drawnColours()").get<std::vector<int>>();
  REQUIRE(coverage.size() == own.size());
  int green = 0;
  int other = 0;
  for (std::size_t i = 0; i < coverage.size(); i += 3) {
    const std::array<int, 3> c = {coverage[i], coverage[i + 1], coverage[i + 2]};
    if (c == std::array<int, 3>{40, 200, 70}) {
      ++green;
    } else if (c != std::array<int, 3>{255, 150, 20} && c != std::array<int, 3>{230, 40, 40}) {
      ++other;
    }
  }
  CHECK(green == well_covered);
  CHECK(other == 0);
  CHECK(browser.Evaluate("window.flysfmView.colouring") == "coverage");

  ChooseColouring(browser, "uncertainty");
  browser.Screenshot(ArtifactDir() / "view_uncertainty.png");
  const std::vector<int> uncertainty =
      browser.Evaluate("window.flysfmView.drawnColours()").get<std::vector<int>>();
  CHECK(uncertainty != coverage);
  CHECK(uncertainty != own);
  CHECK(browser.Evaluate("document.getElementById('legend').textContent")
            .get<std::string>()
            .find("undefined") != std::string::npos);

  ChooseColouring(browser, "colour");
  CHECK(browser.Evaluate("window.flysfmView.drawnColours()").get<std::vector<int>>() == own);
  CHECK(browser.Evaluate("window.flysfmView.errors").empty());
  for (const std::string& error : browser.errors()) FAIL_CHECK("browser: " << error);
}

// The coverage surface and the suggested viewpoints of the finished page are
// summary.json's: the share, one ghost camera and one listed reason per
// suggestion, in its order.
void CheckSurface(testing::HeadlessBrowser& browser, const std::filesystem::path& out) {
  const nlohmann::json summary = nlohmann::json::parse(testing::ReadText(out / "summary.json"));
  REQUIRE(summary.contains("coverage"));
  const nlohmann::json& coverage = summary["coverage"];
  const nlohmann::json state = browser.Evaluate(
      "(() => { const v = window.flysfmView; return {faces: v.surfaceFaces, share: v.surfaceShare, "
      "suggestions: v.suggestions, ghosts: v.ghosts, "
      "listed: Array.from(document.querySelectorAll('#suggestions li')).map(li => li.textContent)}; "
      "})()");
  INFO("page " << state.dump() << "\nsummary " << coverage.dump());
  CHECK(state["faces"] == coverage["faces"]);
  REQUIRE(coverage["faces"].get<int>() > 0);
  CHECK(state["share"].get<double>() == Approx(coverage["well_covered_share"].get<double>()));
  std::vector<std::string> reasons;
  for (const nlohmann::json& suggestion : coverage["suggestions"]) {
    reasons.push_back(suggestion["reason"].get<std::string>());
  }
  CHECK(state["suggestions"].get<std::vector<std::string>>() == reasons);
  CHECK(state["listed"].get<std::vector<std::string>>() == reasons);
  CHECK(state["ghosts"].get<std::size_t>() == reasons.size());
  browser.Screenshot(ArtifactDir() / "view_surface.png");
}

struct Run {
  std::filesystem::path dir;
  std::filesystem::path out;
  std::filesystem::path output;
  pid_t pid = -1;
};

Run StartBatch(const std::string& name, double interval) {
  Run run;
  run.dir = testing::MakeTempDir(name);
  const std::string camera = WriteCapture(run.dir / "shots");
  run.out = run.dir / "out";
  run.output = run.dir / "batch.txt";
  run.pid = testing::SpawnFlysfm({"batch", (run.dir / "shots").string(), "--out",
                                  run.out.string(), "--camera", camera, "--interval",
                                  std::to_string(interval), "--view=0", "--view-keep"},
                                 run.output);
  return run;
}

void StopBatch(const Run& run) {
  ::kill(run.pid, SIGINT);
  const int code = testing::WaitForExit(run.pid, 30);
  INFO(testing::ReadText(run.output));
  CHECK(code == 0);
}

TEST_CASE("view: a page opened as the run starts ends showing the run's model") {
  const std::filesystem::path chromium = Chromium();
  const Run run = StartBatch("view_start", 0.2);
  const std::string url = ViewUrl(run.output);
  {
    testing::HeadlessBrowser browser(chromium, run.dir / "profile");
    browser.Navigate(url);
    CheckFinishedPage(browser, run.out, ArtifactDir() / "view_start.png");
    CheckFailedShot(browser);
    CheckColourings(browser, run.out);
    CheckSurface(browser, run.out);
  }
  StopBatch(run);
}

TEST_CASE("view: a page opened mid-run gets the model so far and then the rest") {
  const std::filesystem::path chromium = Chromium();
  const Run run = StartBatch("view_mid_run", 1.5);
  const std::string url = ViewUrl(run.output);
  // Half the shots processed before the page opens.
  REQUIRE(testing::WaitUntil(
      [&] { return testing::LinesStartingWith(run.out / "log.jsonl", "{").size() >= kViews / 2; },
      120));
  {
    testing::HeadlessBrowser browser(chromium, run.dir / "profile");
    browser.Navigate(url);
    CheckFinishedPage(browser, run.out, ArtifactDir() / "view_mid_run.png");
    // It came in mid-run: the model first, then updates for the later shots.
    CHECK(PageState(browser)["updates"].get<int>() >= 1);
  }
  StopBatch(run);
}

}  // namespace
}  // namespace flysfm
