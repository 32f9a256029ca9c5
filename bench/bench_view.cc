// The live view's cost. (1) Per update, on the engine thread: a synthetic
// model grows image by image (500 new points each, a local BA moving the
// last 8 images and their points), and each step is published to a view
// with one page connected (a reading socket). Figures: bytes and ms of
// Publish per update around image 100 and image 1000; they must not grow
// with the model. (2) In headless chromium: a model of --points points
// (1 million) sent to the page, then the mean frame time while the view
// orbits (the page then draws a subset, docs/view.md) and when it is still,
// as the page measures it; then the same with a coverage surface of the
// largest size Coverage makes (quality/coverage.h: at most max_points
// vertices, so a closed surface of 2 max_points - 4 faces) and its
// suggested viewpoints added. Ends with one line of JSON.
//
//   bench_view [--images N] [--points P] [--skip-browser]

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/view/view_server.h"
#include "quality/coverage.h"
#include "tests/testing/headless_browser.h"
#include "tests/testing/temp_dir.h"

namespace flysfm {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kNewPointsPerImage = 500;
constexpr int kBaWindow = 8;

// A page that reads everything the server sends, on its own thread.
class DrainingReader {
 public:
  explicit DrainingReader(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
      throw std::runtime_error("cannot connect to the view");
    }
    const std::string request = "GET /events HTTP/1.1\r\nHost: bench\r\n\r\n";
    if (::write(fd_, request.data(), request.size()) != ssize_t(request.size())) {
      throw std::runtime_error("cannot ask for the events");
    }
    thread_ = std::thread([this] {
      char buffer[1 << 16];
      while (true) {
        const ssize_t n = ::read(fd_, buffer, sizeof(buffer));
        if (n <= 0) break;
        bytes_ += std::size_t(n);
      }
    });
  }
  ~DrainingReader() {
    ::shutdown(fd_, SHUT_RDWR);
    thread_.join();
    ::close(fd_);
  }
  std::size_t bytes() const { return bytes_; }

 private:
  int fd_ = -1;
  std::atomic<std::size_t> bytes_{0};
  std::thread thread_;
};

// A sphere of radius 10 round the points' disc, its faces cycling through
// the classes, with Coverage's most suggestions round it: the page's largest
// surface message.
ViewSurface LargestSurface() {
  const Coverage::Options options;
  const int target_faces = 2 * options.max_points - 4;
  const int segments = 100;
  const int rings = target_faces / (2 * segments);
  const auto vertex = [&](int ring, int segment) {
    const double theta = M_PI * ring / rings;
    const double phi = 2 * M_PI * segment / segments;
    return Eigen::Vector3d(10 * std::sin(theta) * std::cos(phi), 10 * std::cos(theta),
                           20 + 10 * std::sin(theta) * std::sin(phi));
  };
  ViewSurface surface;
  const auto add_face = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c) {
    for (const Eigen::Vector3d* corner : {&a, &b, &c}) {
      surface.xyz.insert(surface.xyz.end(),
                         {float(corner->x()), float(corner->y()), float(corner->z())});
    }
    surface.classes.push_back(std::uint8_t(surface.classes.size() % 5));
  };
  for (int ring = 0; ring < rings; ++ring) {
    for (int segment = 0; segment < segments; ++segment) {
      const Eigen::Vector3d a = vertex(ring, segment), b = vertex(ring + 1, segment);
      const Eigen::Vector3d c = vertex(ring + 1, segment + 1), d = vertex(ring, segment + 1);
      add_face(a, b, c);
      add_face(a, c, d);
    }
  }
  surface.well_covered_share = 0.2;
  surface.area = 4 * M_PI * 100;
  for (int s = 0; s < options.max_suggestions; ++s) {
    const double phi = 2 * M_PI * s / options.max_suggestions;
    const Eigen::Vector3d centre(25 * std::cos(phi), 0, 20 + 25 * std::sin(phi));
    // Looking at the sphere's centre, image up along -y.
    const Eigen::Vector3d z = (Eigen::Vector3d(0, 0, 20) - centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d(0, 1, 0).cross(z).normalized();
    Eigen::Matrix3d rotation;
    rotation << x.transpose(), z.cross(x).transpose(), z.transpose();
    ViewSurface::Suggestion suggestion;
    suggestion.rotation = Eigen::Quaterniond(rotation);
    suggestion.translation = -(rotation * centre);
    suggestion.area_share = 0.1;
    suggestion.reason = "10 % of the surface, side " + std::to_string(s + 1) + " (bench)";
    surface.suggestions.push_back(suggestion);
  }
  return surface;
}

// The page's mean frame time orbiting (its moving subset) and still.
std::pair<double, double> MeasureFrames(testing::HeadlessBrowser& page_browser) {
  const double orbiting =
      page_browser.Evaluate("window.flysfmView.measureFrames(40, false)").get<double>();
  const double still =
      page_browser.Evaluate("window.flysfmView.measureFrames(5, true)").get<double>();
  return {orbiting, still};
}

struct Window {
  double ms = 0;
  double bytes = 0;
  double points = 0;
  int count = 0;
};

}  // namespace
}  // namespace flysfm

int main(int argc, char** argv) {
  using namespace flysfm;
  int num_images = 1000;
  int page_points = 1000000;
  bool browser = true;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--images") == 0 && i + 1 < argc) {
      num_images = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--points") == 0 && i + 1 < argc) {
      page_points = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--skip-browser") == 0) {
      browser = false;
    } else {
      std::fprintf(stderr, "usage: bench_view [--images N] [--points P] [--skip-browser]\n");
      return 2;
    }
  }
  if (num_images < 100) num_images = 100;

  // --- (1) Publish per update while the model grows -----------------------
  ViewServerOptions options;
  options.port = 0;
  ViewServer server(options);
  DrainingReader page(server.port());
  while (server.num_clients() < 1) std::this_thread::sleep_for(std::chrono::milliseconds(5));

  Reconstruction model;
  const camera_t camera_id =
      model.AddCamera(Camera::FromString("PINHOLE 1000,1000,960,540", 1920, 1080));
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0, 0.01);
  std::vector<std::vector<point3D_t>> points_of(std::size_t(num_images) + 1);
  std::vector<Window> windows(2);
  const int marks[2] = {100, num_images};
  for (int i = 1; i <= num_images; ++i) {
    // Keypoints: its own new points' and the previous image's share of them.
    const std::vector<Eigen::Vector2d> keypoints(2 * kNewPointsPerImage,
                                                 Eigen::Vector2d(100, 100));
    const image_t id = model.AddImage("img" + std::to_string(i) + ".jpg", camera_id, keypoints);
    model.RegisterImage(id, Rigid3d(Eigen::Quaterniond::Identity(),
                                    Eigen::Vector3d(-0.1 * i, 0, 0)));
    if (i > 1) {
      for (int p = 0; p < kNewPointsPerImage; ++p) {
        const point3D_t point = model.AddPoint3D(
            Eigen::Vector3d(0.1 * i + noise(rng), noise(rng), 5 + noise(rng)),
            {{id - 1, point2D_t(kNewPointsPerImage + p)}, {id, point2D_t(p)}},
            {std::uint8_t(p % 255), 100, 200});
        points_of[std::size_t(i)].push_back(point);
      }
    }
    // The local BA: the last images move a little, and so do their points.
    for (int j = std::max(2, i - kBaWindow + 1); j <= i; ++j) {
      const Image& image = model.image(image_t(j));
      Rigid3d pose = *image.cam_from_world;
      pose.translation += Eigen::Vector3d(noise(rng), 0, 0);
      model.RegisterImage(image_t(j), pose);
      for (const point3D_t point : points_of[std::size_t(j)]) {
        model.point3D(point).xyz += Eigen::Vector3d(0, noise(rng), 0);
        model.MarkPointChanged(point);
      }
    }
    ImageResult result;
    result.name = model.image(id).name;
    result.status = ImageStatus::kRegistered;
    result.num_new_points = kNewPointsPerImage;
    const auto start = Clock::now();
    const ViewUpdate update =
        MakeViewUpdate(model, model.TakeChanges(), {MakeViewLine(result, std::nullopt)});
    server.Publish(update);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    for (int w = 0; w < 2; ++w) {
      // The 10 updates up to the mark.
      if (i > marks[w] - 10 && i <= marks[w]) {
        windows[std::size_t(w)].ms += ms;
        windows[std::size_t(w)].bytes += double(UpdateMessage(update, nullptr).size());
        windows[std::size_t(w)].points += double(update.point_ids.size());
        ++windows[std::size_t(w)].count;
      }
    }
  }
  for (Window& w : windows) {
    w.ms /= w.count;
    w.bytes /= w.count;
    w.points /= w.count;
  }
  std::printf("Publish per update (MakeViewUpdate + apply + serialise + enqueue), one page "
              "reading; %d new points per image, local BA over the last %d images:\n",
              kNewPointsPerImage, kBaWindow);
  for (int w = 0; w < 2; ++w) {
    std::printf("  at %5d images (%7zu points in the model): %8.0f bytes, %6.2f ms, "
                "%5.0f points sent\n",
                marks[w], std::size_t(marks[w] - 1) * kNewPointsPerImage, windows[w].bytes,
                windows[w].ms, windows[w].points);
  }
  std::printf("  the page read %.1f MB in all\n", page.bytes() / 1e6);

  // --- (2) a model of a million points in the browser ---------------------
  nlohmann::json page_json = {{"checked", false}};
  if (browser) {
    const std::optional<std::filesystem::path> chromium = testing::FindChromium();
    if (!chromium) {
      std::printf("page check skipped: no chromium on PATH. By hand: run `flysfm view OUT` on a "
                  "large model, open the page, and read 'frame: ... ms' under the buttons\n");
    } else {
      ViewServer big(options);
      ViewUpdate update;
      update.point_ids.reserve(std::size_t(page_points));
      for (int p = 0; p < page_points; ++p) {
        const double a = p * 2.399963;
        const double r = 10 * std::sqrt(double(p) / page_points);
        update.point_ids.push_back(point3D_t(p + 1));
        update.xyz.insert(update.xyz.end(), {float(r * std::cos(a)), float(std::sin(p * 1e-3)),
                                             float(20 + r * std::sin(a))});
        update.rgb.insert(update.rgb.end(), {std::uint8_t(80 + p % 170), 120,
                                             std::uint8_t(200 - p % 150)});
      }
      update.num_points = page_points;
      big.Publish(update);
      const std::filesystem::path profile = testing::MakeTempDir("bench_view_chromium");
      testing::HeadlessBrowser page_browser(*chromium, profile, 120);
      const auto load_start = Clock::now();
      page_browser.Navigate("http://127.0.0.1:" + std::to_string(big.port()) + "/");
      const bool loaded = page_browser.WaitFor(
          "window.flysfmView && window.flysfmView.points === " + std::to_string(page_points),
          300);
      const double load_s = std::chrono::duration<double>(Clock::now() - load_start).count();
      if (!loaded) {
        std::printf("page check failed: the page did not show %d points in 300 s\n",
                    page_points);
      } else {
        // Orbiting (the page draws its moving subset), then still (every point).
        const auto [frame_ms, still_ms] = MeasureFrames(page_browser);
        const int moving_points =
            page_browser.Evaluate("window.flysfmView.movingPoints").get<int>();
        std::printf("page: %d points loaded and drawn in %.1f s, in headless chromium with "
                    "software WebGL (SwiftShader, no GPU): orbiting %.1f ms per frame "
                    "(%.0f frames/s, the page's moving subset of %d points); still, every "
                    "point: %.1f ms per frame\n",
                    page_points, load_s, frame_ms, 1000 / frame_ms, moving_points, still_ms);
        page_json = {{"checked", true},
                     {"points", page_points},
                     {"load_s", load_s},
                     {"frame_ms_orbiting", frame_ms},
                     {"moving_points", moving_points},
                     {"frame_ms_still", still_ms}};
        // The coverage surface and its ghost cameras over the same points.
        ViewUpdate with_surface;
        with_surface.surface = LargestSurface();
        with_surface.num_points = page_points;
        const std::size_t faces = with_surface.surface->classes.size();
        const auto surface_start = Clock::now();
        big.Publish(with_surface);
        const bool drawn = page_browser.WaitFor(
            "window.flysfmView.surfaceFaces === " + std::to_string(faces), 120);
        const double surface_s =
            std::chrono::duration<double>(Clock::now() - surface_start).count();
        if (!drawn) {
          std::printf("page check failed: the page did not show the surface's %zu faces in "
                      "120 s\n", faces);
        } else {
          const auto [surface_frame_ms, surface_still_ms] = MeasureFrames(page_browser);
          std::printf("page with the surface (%zu faces, %zu suggested viewpoints) shown in "
                      "%.1f s: orbiting %.1f ms per frame (%.0f frames/s); still %.1f ms per "
                      "frame\n",
                      faces, with_surface.surface->suggestions.size(), surface_s,
                      surface_frame_ms, 1000 / surface_frame_ms, surface_still_ms);
          page_json["surface"] = {{"faces", faces},
                                  {"suggestions", with_surface.surface->suggestions.size()},
                                  {"shown_s", surface_s},
                                  {"frame_ms_orbiting", surface_frame_ms},
                                  {"frame_ms_still", surface_still_ms}};
        }
        page_json["errors"] = page_browser.errors().size();
      }
    }
  }

  const nlohmann::json json = {
      {"bench", "view"},
      {"updates", {{{"images", marks[0]}, {"bytes", windows[0].bytes}, {"ms", windows[0].ms}},
                   {{"images", marks[1]}, {"bytes", windows[1].bytes}, {"ms", windows[1].ms}}}},
      {"page", page_json}};
  std::cout << json.dump() << "\n";
  return 0;
}
