#include "rt/view/viewer.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <fmt/format.h>

#include "rt/core/error.h"
#include "rt/io/image_io.h"
#include "rt/render/effects.h"
#include "rt/view/orbit.h"

namespace rt {

namespace {

constexpr int kPreviewScale = 8;            // the preview's pixels are 8x8 image pixels
constexpr double kOrbitRadiansPerPixel = 0.005;
constexpr double kZoomPerWheelStep = 0.9;   // distance to the target multiplied per step towards it

std::string glfw_error() {
  const char* description = nullptr;
  glfwGetError(&description);
  return description ? description : "unknown GLFW error";
}

// "shadows, 1 area light x 16 samples, reflections to depth 2, 4 spp": what the renders compute,
// for the title bar.
std::string effects_summary(const EffectsPlan& plan, int spp) {
  std::vector<std::string> parts;
  parts.push_back(plan.shadows ? "shadows" : "no shadows");
  if (!plan.emitters.empty())
    parts.push_back(fmt::format("{} area light{} x {} samples", plan.emitters.size(), plan.emitters.size() == 1 ? "" : "s",
                                plan.options.light_samples));
  parts.push_back(plan.reflections ? fmt::format("reflections to depth {}", plan.useful_depth) : "no reflections");
  parts.push_back(spp > 1 ? fmt::format("{} spp", spp) : "1 spp");
  return fmt::format("{}", fmt::join(parts, ", "));
}

// What the window shows, written by the render thread tile by tile and read by the window thread.
struct Frame {
  std::mutex mutex;
  Image colors;                     // linear float RGB of the pixels shown (S saves these)
  std::vector<std::uint8_t> rgb8;   // the same, quantised as rt render writes them
  int dirty_y0 = 0, dirty_y1 = 0;   // rows [y0, y1) of rgb8 changed since the last texture upload
  bool complete = false;            // the full render (every sample) is in
  std::string status = "starting";  // progress and speed, for the title bar
  std::string error;                // a render that threw
  DisplayTransform display;         // how rgb8 encodes colors, as rt render's 8-bit files

  Frame(int width, int height, const DisplayTransform& display_transform)
      : colors(width, height), rgb8(colors.pixels.size() * 3, 0), dirty_y1(height), display(display_transform) {}

  // Marks rows [y0, y1) for the next upload.
  void touch(int y0, int y1) {
    if (dirty_y0 == dirty_y1) {
      dirty_y0 = y0;
      dirty_y1 = y1;
    } else {
      dirty_y0 = std::min(dirty_y0, y0);
      dirty_y1 = std::max(dirty_y1, y1);
    }
  }

  void set(int x, int y, const Color& c) {
    colors.at(x, y) = c;
    std::uint8_t* bytes = &rgb8[(std::size_t(y) * std::size_t(colors.width) + std::size_t(x)) * 3];
    encode_8bit(c, display, bytes);
  }
};

// Renders the scene for one camera after another on a thread of its own: restart() abandons the
// render in progress (RenderOptions::cancel) and starts again from the preview.
class ProgressiveRenderer {
 public:
  ProgressiveRenderer(const Scene& scene, const FlatScene& flat, const Accel& accel, const RenderOptions& options,
                      Frame& frame)
      : scene_(scene), flat_(flat), accel_(accel), options_(options), frame_(frame) {}
  ~ProgressiveRenderer() { stop(); }
  ProgressiveRenderer(const ProgressiveRenderer&) = delete;
  ProgressiveRenderer& operator=(const ProgressiveRenderer&) = delete;

  void restart(const Camera& camera) {
    stop();
    {
      std::lock_guard lock(frame_.mutex);
      frame_.complete = false;
      frame_.error.clear();
    }
    cancel_.store(false);
    thread_ = std::thread([this, camera] { run(camera); });
  }

  void stop() {
    cancel_.store(true);
    if (thread_.joinable()) thread_.join();
  }

 private:
  void run(const Camera& camera) {
    try {
      render_progressively(camera);
    } catch (const std::exception& error) {
      std::lock_guard lock(frame_.mutex);
      frame_.error = error.what();
      frame_.status = "failed";
    }
  }

  void render_progressively(const Camera& camera) {
    using Clock = std::chrono::steady_clock;
    const auto start = Clock::now();
    Scene view = scene_;
    view.camera = camera;
    const int width = view.settings.width, height = view.settings.height;
    RenderOptions options = options_;
    options.cancel = &cancel_;
    options.region.reset();

    // Preview: every kPreviewScale x kPreviewScale block of pixels shows the colour at its centre
    // of a render at that lower resolution (same camera and field of view).
    if (width >= 2 * kPreviewScale || height >= 2 * kPreviewScale) {
      Scene preview = view;
      preview.settings.width = (width + kPreviewScale - 1) / kPreviewScale;
      preview.settings.height = (height + kPreviewScale - 1) / kPreviewScale;
      options.samples_per_pixel = 1;
      options.sample_index = -1;
      options.on_tile = [&](const PixelRegion& tile, const Image& image) {
        std::lock_guard lock(frame_.mutex);
        for (int y = tile.y0; y < tile.y1; ++y)
          for (int x = tile.x0; x < tile.x1; ++x)
            for (int py = y * kPreviewScale; py < std::min((y + 1) * kPreviewScale, height); ++py)
              for (int px = x * kPreviewScale; px < std::min((x + 1) * kPreviewScale, width); ++px)
                frame_.set(px, py, image.at(x, y));
        frame_.touch(tile.y0 * kPreviewScale, std::min(tile.y1 * kPreviewScale, height));
      };
      options.on_progress = [&](double fraction) {
        std::lock_guard lock(frame_.mutex);
        frame_.status = fmt::format("preview {:.0f}%", 100.0 * fraction);
      };
      if (render_image(preview, flat_, accel_, options).cancelled()) return;
    }

    // Full resolution, one sample per pass when anti-aliasing: the running average of the samples
    // so far (double sums in sample order, as render_image averages them), exact after the last.
    const int spp = std::max(1, options_.samples_per_pixel);
    std::vector<Vec3d> sums(spp > 1 ? std::size_t(width) * std::size_t(height) : 0, Vec3d(0.0));
    std::uint64_t rays = 0;
    double render_seconds = 0.0;
    options.samples_per_pixel = spp;
    for (int s = 0; s < spp; ++s) {
      options.sample_index = spp > 1 ? s : -1;
      options.on_tile = [&](const PixelRegion& tile, const Image& image) {
        std::lock_guard lock(frame_.mutex);
        for (int y = tile.y0; y < tile.y1; ++y)
          for (int x = tile.x0; x < tile.x1; ++x) {
            if (spp == 1) {
              frame_.set(x, y, image.at(x, y));
              continue;
            }
            Vec3d& sum = sums[std::size_t(y) * std::size_t(width) + std::size_t(x)];
            sum += Vec3d(image.at(x, y));
            frame_.set(x, y, Color(sum / double(s + 1)));
          }
        frame_.touch(tile.y0, tile.y1);
      };
      const std::string pass = spp > 1 ? fmt::format("sample {}/{}", s + 1, spp) : "full resolution";
      const double mrays = render_seconds > 0.0 ? double(rays) / render_seconds / 1e6 : 0.0;
      options.on_progress = [&](double fraction) {
        std::lock_guard lock(frame_.mutex);
        frame_.status = mrays > 0.0 ? fmt::format("{} {:.0f}%, {:.1f} Mrays/s", pass, 100.0 * fraction, mrays)
                                    : fmt::format("{} {:.0f}%", pass, 100.0 * fraction);
      };
      const RenderResult result = render_image(view, flat_, accel_, options);
      if (result.cancelled()) return;
      rays += result.rays.total();
      render_seconds += result.seconds;
    }
    std::lock_guard lock(frame_.mutex);
    frame_.status = fmt::format("done in {:.2f} s, {:.1f} Mrays/s",
                                std::chrono::duration<double>(Clock::now() - start).count(),
                                double(rays) / std::max(render_seconds, 1e-9) / 1e6);
    frame_.complete = true;
  }

  const Scene& scene_;
  const FlatScene& flat_;
  const Accel& accel_;
  const RenderOptions options_;
  Frame& frame_;
  std::atomic<bool> cancel_{false};
  std::thread thread_;
};

// The image drawn from a texture by one full-window triangle, with nearest-texel sampling, so that
// a viewport of the image's size shows its bytes unchanged.
class ImageProgram {
 public:
  ImageProgram(int width, int height) {
    const char* vertex_source = R"(#version 330 core
out vec2 uv;
void main() {
  vec2 corner = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
  uv = vec2(0.5 * corner.x + 0.5, 0.5 - 0.5 * corner.y);  // texture row 0 is the image's top row
  gl_Position = vec4(corner, 0.0, 1.0);
})";
    const char* fragment_source = R"(#version 330 core
in vec2 uv;
out vec4 color;
uniform sampler2D image;
void main() { color = vec4(texture(image, uv).rgb, 1.0); })";
    program_ = glCreateProgram();
    const GLuint vertex = compile(GL_VERTEX_SHADER, vertex_source);
    const GLuint fragment = compile(GL_FRAGMENT_SHADER, fragment_source);
    glAttachShader(program_, vertex);
    glAttachShader(program_, fragment);
    glLinkProgram(program_);
    glDeleteShader(vertex);
    glDeleteShader(fragment);
    GLint linked = 0;
    glGetProgramiv(program_, GL_LINK_STATUS, &linked);
    if (!linked) throw RuntimeError("rt view: the OpenGL display program does not link");
    glGenVertexArrays(1, &vertex_array_);
    glGenTextures(1, &texture_);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, width, height, 0, GL_RGB, GL_UNSIGNED_BYTE, nullptr);
    width_ = width;
    height_ = height;
  }
  ~ImageProgram() {
    glDeleteTextures(1, &texture_);
    glDeleteVertexArrays(1, &vertex_array_);
    glDeleteProgram(program_);
  }
  ImageProgram(const ImageProgram&) = delete;
  ImageProgram& operator=(const ImageProgram&) = delete;

  // Copies rows [y0, y1) of the image (interleaved 8-bit RGB, rows top to bottom) into the texture.
  void upload(const std::vector<std::uint8_t>& rgb8, int y0, int y1) {
    glBindTexture(GL_TEXTURE_2D, texture_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, y0, width_, y1 - y0, GL_RGB, GL_UNSIGNED_BYTE,
                    rgb8.data() + std::size_t(y0) * std::size_t(width_) * 3);
  }

  // Draws the image into the bound framebuffer's viewport (x, y, w, h), in pixels.
  void draw(int x, int y, int w, int h) const {
    glViewport(x, y, w, h);
    glUseProgram(program_);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glUniform1i(glGetUniformLocation(program_, "image"), 0);
    glBindVertexArray(vertex_array_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

 private:
  static GLuint compile(GLenum kind, const char* source) {
    const GLuint shader = glCreateShader(kind);
    glShaderSource(shader, 1, &source, nullptr);
    glCompileShader(shader);
    GLint compiled = 0;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &compiled);
    if (!compiled) throw RuntimeError("rt view: an OpenGL display shader does not compile");
    return shader;
  }

  GLuint program_ = 0, vertex_array_ = 0, texture_ = 0;
  int width_ = 0, height_ = 0;
};

// Draws the image at its own size into an offscreen framebuffer and reads it back, rows top to
// bottom: what the window shows at 1:1, whatever the window's size.
std::vector<std::uint8_t> read_back(const ImageProgram& program, int width, int height) {
  GLuint framebuffer = 0, color = 0;
  glGenFramebuffers(1, &framebuffer);
  glGenRenderbuffers(1, &color);
  glBindRenderbuffer(GL_RENDERBUFFER, color);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color);
  const bool complete = glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
  std::vector<std::uint8_t> bottom_up(std::size_t(width) * std::size_t(height) * 3);
  if (complete) {
    program.draw(0, 0, width, height);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, bottom_up.data());
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glDeleteRenderbuffers(1, &color);
  glDeleteFramebuffers(1, &framebuffer);
  if (!complete) throw RuntimeError("rt view: cannot create an offscreen framebuffer for the screenshot");
  std::vector<std::uint8_t> rgb8(bottom_up.size());
  const std::size_t row = std::size_t(width) * 3;
  for (int y = 0; y < height; ++y)
    std::copy_n(bottom_up.begin() + std::ptrdiff_t(std::size_t(height - 1 - y) * row), row,
                rgb8.begin() + std::ptrdiff_t(std::size_t(y) * row));
  return rgb8;
}

// Clears the window's framebuffer and draws the image centred, as large as fits with its aspect
// ratio kept.
void draw_letterboxed(const ImageProgram& program, int framebuffer_width, int framebuffer_height, int width,
                      int height) {
  glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
  glViewport(0, 0, framebuffer_width, framebuffer_height);
  glClear(GL_COLOR_BUFFER_BIT);
  const double scale = std::min(double(framebuffer_width) / width, double(framebuffer_height) / height);
  const int shown_width = int(std::lround(width * scale)), shown_height = int(std::lround(height * scale));
  program.draw((framebuffer_width - shown_width) / 2, (framebuffer_height - shown_height) / 2, shown_width,
               shown_height);
}

// Input state the GLFW callbacks update (through the window's user pointer).
struct Input {
  Camera camera;
  bool camera_changed = false;
  bool rerender = false;
  bool save = false;
  bool refresh = false;  // the window system asks for a redraw (exposed, restored)
  bool dragging = false;
  double last_x = 0.0, last_y = 0.0;
};

void on_key(GLFWwindow* window, int key, int, int action, int) {
  if (action != GLFW_PRESS) return;
  Input& input = *static_cast<Input*>(glfwGetWindowUserPointer(window));
  if (key == GLFW_KEY_Q || key == GLFW_KEY_ESCAPE) glfwSetWindowShouldClose(window, GLFW_TRUE);
  if (key == GLFW_KEY_R) input.rerender = true;
  if (key == GLFW_KEY_S) input.save = true;
}

void on_mouse_button(GLFWwindow* window, int button, int action, int) {
  if (button != GLFW_MOUSE_BUTTON_LEFT) return;
  Input& input = *static_cast<Input*>(glfwGetWindowUserPointer(window));
  input.dragging = action == GLFW_PRESS;
  glfwGetCursorPos(window, &input.last_x, &input.last_y);
}

void on_cursor(GLFWwindow* window, double x, double y) {
  Input& input = *static_cast<Input*>(glfwGetWindowUserPointer(window));
  if (!input.dragging) return;
  // Dragging right turns the scene to the right (the eye to the left); dragging up raises the eye.
  input.camera = orbit_camera(input.camera, -(x - input.last_x) * kOrbitRadiansPerPixel,
                              (y - input.last_y) * kOrbitRadiansPerPixel);
  input.last_x = x;
  input.last_y = y;
  input.camera_changed = true;
}

void on_refresh(GLFWwindow* window) { static_cast<Input*>(glfwGetWindowUserPointer(window))->refresh = true; }

void on_scroll(GLFWwindow* window, double, double steps) {
  Input& input = *static_cast<Input*>(glfwGetWindowUserPointer(window));
  input.camera = zoom_camera(input.camera, std::pow(kZoomPerWheelStep, steps));
  input.camera_changed = true;
}

// The window's size in screen coordinates: the image's, scaled down to 90% of the monitor's work
// area when larger.
std::pair<int, int> window_size(int width, int height) {
  double scale = 1.0;
  if (GLFWmonitor* monitor = glfwGetPrimaryMonitor()) {
    int x = 0, y = 0, w = 0, h = 0;
    glfwGetMonitorWorkarea(monitor, &x, &y, &w, &h);
    if (w > 0 && h > 0) scale = std::min({1.0, 0.9 * w / width, 0.9 * h / height});
  }
  return {std::max(1, int(width * scale)), std::max(1, int(height * scale))};
}

}  // namespace

void check_display() {
#if GLFW_VERSION_MAJOR > 3 || (GLFW_VERSION_MAJOR == 3 && GLFW_VERSION_MINOR >= 4)
  // GLFW 3.4 (Debian 13) also tries Wayland, whose client library prints a line of its own when
  // there is no Wayland session; without one, X11 is the only window system to try.
  if (!std::getenv("WAYLAND_DISPLAY")) glfwInitHint(GLFW_PLATFORM, GLFW_PLATFORM_X11);
#endif
  if (glfwInit() == GLFW_TRUE) return;
  throw RuntimeError(fmt::format("rt view needs a window system and cannot open a window here ({}); "
                                 "render to a file instead: rt render SCENE -o image.png",
                                 glfw_error()));
}

int run_viewer(const Scene& scene, const FlatScene& flat, const Accel& accel, const ViewOptions& options) {
  check_display();
  const int width = scene.settings.width, height = scene.settings.height;
  const EffectsPlan plan = plan_effects(scene, flat, options.render.ray_offset, options.render.effects);
  const std::string effects = effects_summary(plan, std::max(1, options.render.samples_per_pixel));

  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  const auto [window_width, window_height] = window_size(width, height);
  GLFWwindow* window = glfwCreateWindow(window_width, window_height, "rt view", nullptr, nullptr);
  if (!window) {
    const std::string reason = glfw_error();
    glfwTerminate();
    throw RuntimeError(fmt::format("rt view cannot open an OpenGL 3.3 window ({}); render to a file instead: "
                                   "rt render SCENE -o image.png", reason));
  }
  glfwMakeContextCurrent(window);
  glfwSwapInterval(1);

  int status = 0;
  {
    Frame frame(width, height, scene.settings.display);
    ImageProgram program(width, height);
    Input input;
    input.camera = scene.camera;
    glfwSetWindowUserPointer(window, &input);
    glfwSetKeyCallback(window, on_key);
    glfwSetMouseButtonCallback(window, on_mouse_button);
    glfwSetCursorPosCallback(window, on_cursor);
    glfwSetScrollCallback(window, on_scroll);
    glfwSetWindowRefreshCallback(window, on_refresh);

    ProgressiveRenderer renderer(scene, flat, accel, options.render, frame);
    renderer.restart(input.camera);
    bool screenshot_taken = false, reported = false;
    int drawn_width = 0, drawn_height = 0;
    std::string title;
    // Pixels are uploaded and drawn at most 30 times a second, and less often when a draw is slow:
    // after a draw taking T seconds the next waits at least 10 T, so that the display never takes
    // more than a tenth of a core from the render (Mesa's software OpenGL draws on the CPU). The
    // finished image, a resize and an expose are drawn at once.
    using Clock = std::chrono::steady_clock;
    constexpr double kFrameSeconds = 1.0 / 30.0;
    auto next_draw = Clock::now();
    while (!glfwWindowShouldClose(window)) {
      glfwWaitEventsTimeout(kFrameSeconds);
      if (input.camera_changed || input.rerender) {
        renderer.restart(input.camera);
        input.camera_changed = input.rerender = false;
        reported = false;
      }
      bool complete = false, dirty = false;
      std::string frame_status, error;
      {
        std::lock_guard lock(frame.mutex);
        dirty = frame.dirty_y0 < frame.dirty_y1;
        complete = frame.complete;
        frame_status = frame.status;
        error = frame.error;
      }
      if (input.save) {
        input.save = false;
        try {
          Image shown;
          {
            std::lock_guard lock(frame.mutex);
            shown = frame.colors;
          }
          write_image(shown, options.save_path, {}, scene.settings.display);
          fmt::print(stderr, "rt view: saved {}{}\n", options.save_path, complete ? "" : " (render not finished)");
        } catch (const std::exception& failure) {
          fmt::print(stderr, "rt view: error: {}\n", printable_line(failure.what()));
        }
      }

      int framebuffer_width = 0, framebuffer_height = 0;
      glfwGetFramebufferSize(window, &framebuffer_width, &framebuffer_height);
      const bool resized = framebuffer_width != drawn_width || framebuffer_height != drawn_height;
      if ((dirty && (complete || Clock::now() >= next_draw)) || resized || input.refresh) {
        const auto draw_start = Clock::now();
        {
          std::lock_guard lock(frame.mutex);
          if (frame.dirty_y0 < frame.dirty_y1) program.upload(frame.rgb8, frame.dirty_y0, frame.dirty_y1);
          frame.dirty_y0 = frame.dirty_y1 = 0;
        }
        draw_letterboxed(program, framebuffer_width, framebuffer_height, width, height);
        glfwSwapBuffers(window);
        const double draw_seconds = std::chrono::duration<double>(Clock::now() - draw_start).count();
        next_draw = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                       std::chrono::duration<double>(std::max(kFrameSeconds, 10.0 * draw_seconds)));
        input.refresh = false;
        drawn_width = framebuffer_width;
        drawn_height = framebuffer_height;
      }

      const std::string new_title = fmt::format("rt view: {} | {} | {} | drag: orbit, wheel: zoom, R, S, Q",
                                                options.scene_name, frame_status, effects);
      if (new_title != title) glfwSetWindowTitle(window, new_title.c_str());
      title = new_title;

      if (!error.empty()) {
        fmt::print(stderr, "rt view: error: {}\n", printable_line(error));
        status = 1;
        if (options.exit_when_done) break;
        std::lock_guard lock(frame.mutex);
        frame.error.clear();
      }
      if (!complete) continue;
      if (!reported && !options.quiet) fmt::print(stderr, "rt view: {}x{} {}\n", width, height, frame_status);
      reported = true;
      if (!options.screenshot_path.empty() && !screenshot_taken) {
        screenshot_taken = true;
        try {
          write_rgb8(width, height, read_back(program, width, height), options.screenshot_path);
          if (!options.quiet) fmt::print(stderr, "rt view: screenshot {}\n", options.screenshot_path);
        } catch (const std::exception& failure) {
          fmt::print(stderr, "rt view: error: {}\n", printable_line(failure.what()));
          status = 1;
        }
      }
      if (options.exit_when_done) break;
    }
    renderer.stop();
    if (!options.screenshot_path.empty() && !screenshot_taken) {
      fmt::print(stderr, "rt view: the window was closed before the render was complete; {} not written\n",
                 options.screenshot_path);
      status = 1;
    }
  }
  glfwDestroyWindow(window);
  glfwTerminate();
  return status;
}

}  // namespace rt
