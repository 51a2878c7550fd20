// rt view: the camera moves, the no-display error, and screenshots from a real window (Xvfb with
// Mesa's software OpenGL) against rt render's image of the same scene.

#include "catch.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>

#include "rt/io/image_io.h"
#include "rt/view/orbit.h"
#include "test_util.h"

extern char** environ;

namespace {

double distance_to_target(const rt::Camera& camera) { return glm::length(camera.eye - camera.target); }

// Angle in radians between the view offset (target -> eye) and the up vector.
double elevation(const rt::Camera& camera) {
  return std::acos(glm::dot(glm::normalize(camera.eye - camera.target), glm::normalize(camera.up)));
}

// An Xvfb server on a free display number, stopped by its pid when the object goes away.
class Xvfb {
 public:
  // Starts Xvfb (24-bit screen of 1280x1024) and waits until it has chosen its display, which it
  // writes to the -displayfd pipe once it accepts connections. Empty when Xvfb is not installed.
  static std::optional<Xvfb> start() {
    const char* const binary = "/usr/bin/Xvfb";
    if (access(binary, X_OK) != 0) return std::nullopt;
    int fds[2];
    if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
    const std::string fd = std::to_string(fds[1]);
    const char* argv[] = {binary, "-displayfd", fd.c_str(), "-screen", "0", "1280x1024x24", "-nolisten", "tcp", nullptr};
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);  // its log
    pid_t pid = 0;
    const int spawned = posix_spawn(&pid, binary, &actions, nullptr, const_cast<char**>(argv), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    if (spawned != 0) {
      close(fds[0]);
      throw std::runtime_error("cannot start Xvfb: " + std::string(std::strerror(spawned)));
    }
    std::string display;
    char c = 0;
    while (read(fds[0], &c, 1) == 1 && c != '\n') display += c;
    close(fds[0]);
    Xvfb server(pid, ":" + display);
    if (display.empty()) throw std::runtime_error("Xvfb exited without opening a display");
    return server;
  }

  Xvfb(Xvfb&& other) noexcept : pid_(other.pid_), display_(std::move(other.display_)) { other.pid_ = 0; }
  Xvfb(const Xvfb&) = delete;
  Xvfb& operator=(const Xvfb&) = delete;
  Xvfb& operator=(Xvfb&&) = delete;
  ~Xvfb() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    waitpid(pid_, nullptr, 0);
  }

  const std::string& display() const { return display_; }

 private:
  Xvfb(pid_t pid, std::string display) : pid_(pid), display_(std::move(display)) {}
  pid_t pid_ = 0;
  std::string display_;
};

// Differing pixels between two images of equal size (any channel), or -1 when the sizes differ.
long differing_pixels(const rt::Image& a, const rt::Image& b) {
  if (a.width != b.width || a.height != b.height) return -1;
  long count = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) count += a.pixels[i] != b.pixels[i];
  return count;
}

}  // namespace

TEST_CASE("orbit_camera turns the eye around the target at a constant distance, stopping short of the up axis", "[view]") {
  rt::Camera camera;
  camera.eye = rt::Vec3d(1.0, 2.0, 6.0);
  camera.target = rt::Vec3d(1.0, 0.5, 0.0);
  camera.up = rt::Vec3d(0.0, 1.0, 0.0);
  const double distance = distance_to_target(camera);

  const rt::Camera yawed = rt::orbit_camera(camera, 0.7, 0.0);
  CHECK(distance_to_target(yawed) == Approx(distance).epsilon(1e-12));
  CHECK(elevation(yawed) == Approx(elevation(camera)).epsilon(1e-12));  // a yaw keeps the height
  CHECK(yawed.eye.y == Approx(camera.eye.y).epsilon(1e-12));
  CHECK(glm::length(yawed.eye - camera.eye) > 1.0);
  CHECK(yawed.target == camera.target);
  CHECK(yawed.up == camera.up);

  const rt::Camera raised = rt::orbit_camera(camera, 0.0, 0.2);
  CHECK(distance_to_target(raised) == Approx(distance).epsilon(1e-12));
  CHECK(elevation(raised) == Approx(elevation(camera) - 0.2).epsilon(1e-12));
  CHECK(raised.eye.y > camera.eye.y);
  CHECK(raised.eye.x == Approx(camera.eye.x).margin(1e-12));  // pitch stays in the vertical plane

  const double one_degree = 3.14159265358979323846 / 180.0;
  CHECK(elevation(rt::orbit_camera(camera, 0.0, 10.0)) == Approx(one_degree).epsilon(1e-9));
  CHECK(elevation(rt::orbit_camera(camera, 0.0, -10.0)) == Approx(179.0 * one_degree).epsilon(1e-9));

  // Going round in a full turn of yaw comes back.
  const rt::Camera round = rt::orbit_camera(camera, 2.0 * 3.14159265358979323846, 0.0);
  CHECK(glm::length(round.eye - camera.eye) < 1e-9);
}

TEST_CASE("zoom_camera scales the distance to the target along the view line", "[view]") {
  rt::Camera camera;
  camera.eye = rt::Vec3d(0.0, 3.0, 4.0);
  const rt::Camera closer = rt::zoom_camera(camera, 0.5);
  CHECK(distance_to_target(closer) == Approx(2.5).epsilon(1e-15));
  CHECK(glm::length(glm::cross(closer.eye - camera.target, camera.eye - camera.target)) < 1e-12);
  CHECK(distance_to_target(rt::zoom_camera(camera, 0.0)) > 0.0);
}

TEST_CASE("rt view without a display exits 1 with one line pointing to rt render", "[view][cli]") {
  rt_test::TempDir cwd;
  const rt_test::RtRun run =
      rt_test::run_in(cwd, "/usr/bin/env", "-u DISPLAY -u WAYLAND_DISPLAY '" + std::string(RT_EXECUTABLE) + "' view");
  CHECK(run.status == 1);
  CHECK(run.err.starts_with("rt: error: rt view needs a window system"));
  CHECK(run.err.find("rt render") != std::string::npos);
  CHECK(std::count(run.err.begin(), run.err.end(), '\n') == 1);
  CHECK(cwd.entries().empty());
}

TEST_CASE("rt view --screenshot shows exactly the pixels rt render writes, in a real window", "[view][xvfb]") {
  std::optional<Xvfb> server = Xvfb::start();
  if (!server) {
    WARN("skipped: Xvfb is not installed (tools/install-deps installs xvfb and Mesa's software OpenGL)");
    return;
  }
  const std::string scenes = std::string(RT_SOURCE_DIR) + "/scenes/";
  struct Case {
    std::string scene, options, exit;
  };
  // The default scene (shadows, reflections to depth 5) at one sample per pixel, and the Cornell
  // box anti-aliased, which rt view accumulates one sample per pass. --screenshot alone closes the
  // window too: without it implying --exit-when-done, the second case would never end.
  for (const Case& c : {Case{scenes + "default.json", "--width 320 --height 240", " --exit-when-done"},
                        Case{scenes + "cornell-box.json", "--width 200 --height 150 --spp 4", ""}}) {
    INFO(c.scene << " " << c.options);
    rt_test::TempDir cwd;
    const rt_test::RtRun rendered = rt_test::run_rt_in(cwd, "render '" + c.scene + "' " + c.options + " -o render.png --quiet");
    REQUIRE(rendered.status == 0);
    // LeakSanitizer (asan preset) is off for this process: Mesa's DRI driver leaks 240 bytes in
    // three blocks and is unloaded before the leak check, so no suppression can name it. Every
    // other check of the sanitizers stays on, and every other test keeps the leak check.
    const rt_test::RtRun viewed = rt_test::run_in(
        cwd, "/usr/bin/timeout",
        "300 /usr/bin/env DISPLAY=" + server->display() + " LSAN_OPTIONS=detect_leaks=0 '" + std::string(RT_EXECUTABLE) + "' view '" +
            c.scene + "' " + c.options + " --screenshot view.png" + c.exit);
    INFO(viewed.err);
    REQUIRE(viewed.status == 0);
    CHECK(viewed.err.find("screenshot view.png") != std::string::npos);
    const rt::Image expected = rt::read_image(cwd / "render.png");
    const rt::Image shown = rt::read_image(cwd / "view.png");
    CHECK(differing_pixels(expected, shown) == 0);
  }
}
