#include "rt/app/scene_options.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "rt/scene/framing.h"

namespace rt {

namespace {

// Parses one command-line number as strtod does; nullopt unless the whole text is a finite number.
std::optional<double> parse_finite(const std::string& text) {
  if (text.empty()) return std::nullopt;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

const CLI::Validator kFinite(
    [](std::string& text) -> std::string {
      return parse_finite(text) ? "" : fmt::format("'{}' is not a finite number", text);
    },
    "FINITE");

const CLI::Validator kFovy(
    [](std::string& text) -> std::string {
      const std::optional<double> value = parse_finite(text);
      if (!value) return fmt::format("'{}' is not a finite number", text);
      if (!(*value > 0.0 && *value < 180.0)) return fmt::format("fovy {} is outside (0, 180) degrees", *value);
      return "";
    },
    "DEG in (0, 180)");

Vec3d last3(const std::vector<double>& values) {
  const std::size_t n = values.size();
  return {values[n - 3], values[n - 2], values[n - 1]};
}

Color read_color(const std::vector<double>& values, std::size_t first, const std::string& flag) {
  const Color color(values[first], values[first + 1], values[first + 2]);
  if (color.r < 0 || color.g < 0 || color.b < 0)
    throw UsageError(fmt::format("{}: colour components must be >= 0", flag));
  return color;
}

std::string flag_of(const std::string& field) { return "--" + field; }

// "-z" for a direction along an axis, else its unit vector: "(-0.42, -0.34, -0.84)".
std::string direction_text(const Vec3d& direction) {
  const char* const axes[] = {"x", "y", "z"};
  for (int axis = 0; axis < 3; ++axis)
    if (direction[(axis + 1) % 3] == 0.0 && direction[(axis + 2) % 3] == 0.0 && direction[axis] != 0.0)
      return fmt::format("{}{}", direction[axis] > 0.0 ? "+" : "-", axes[axis]);
  const Vec3d unit = glm::normalize(direction);
  return fmt::format("({:.2f}, {:.2f}, {:.2f})", unit.x, unit.y, unit.z);
}

}  // namespace

void add_scene_options(CLI::App& app, SceneOptions& options) {
  auto vec3 = [&](const char* name, std::vector<double>& values, const char* help) {
    app.add_option(name, values, help)->type_size(3)->allow_extra_args(false)->check(kFinite)->type_name("X Y Z");
  };
  vec3("--eye", options.eye, "Camera position (overrides the scene's; OBJ: the framing's)");
  vec3("--target", options.target, "Point the camera looks at");
  vec3("--up", options.up, "Camera up vector (need not be orthogonal to the view)");
  app.add_option("--fovy", options.fovy, "Vertical field of view in degrees, in (0, 180)")->check(kFovy);
  app.add_option("--point-light", options.point_lights,
                 "Add a point light at X Y Z with colour R G B, unattenuated (repeatable; replaces an OBJ's headlight)")
      ->type_size(6)
      ->allow_extra_args(false)
      ->check(kFinite)
      ->type_name("X Y Z R G B");
  app.add_option("--directional-light", options.directional_lights,
                 "Add a directional light: X Y Z towards the light, colour R G B (repeatable; replaces an OBJ's "
                 "headlight)")
      ->type_size(6)
      ->allow_extra_args(false)
      ->check(kFinite)
      ->type_name("X Y Z R G B");
  app.add_option("--background", options.background, "Colour of rays that miss everything (linear RGB)")
      ->type_size(3)
      ->allow_extra_args(false)
      ->check(kFinite)
      ->type_name("R G B");
}

void apply_scene_options(const SceneOptions& options, const LoadReport& report, Scene& scene) {
  Camera& camera = scene.camera;
  if (report.camera_framed)
    camera = frame_bounds(report.bounds, double(scene.settings.width) / scene.settings.height, report.view,
                          Vec3d(0.0, 1.0, 0.0), options.fovy.value_or(camera.fovy_degrees));
  if (!options.eye.empty()) camera.eye = last3(options.eye);
  if (!options.target.empty()) camera.target = last3(options.target);
  if (!options.up.empty()) camera.up = last3(options.up);
  if (options.fovy) camera.fovy_degrees = *options.fovy;
  if (options.camera_given())
    if (const auto problem = find_camera_problem(camera)) {
      // Name the flag of the offending field if it was given, else the first camera flag given.
      std::string flag = flag_of(problem->field);
      const bool given = (problem->field == "eye" && !options.eye.empty()) ||
                         (problem->field == "target" && !options.target.empty()) ||
                         (problem->field == "up" && !options.up.empty()) ||
                         (problem->field == "fovy" && options.fovy);
      if (!given)
        flag = !options.eye.empty() ? "--eye" : !options.target.empty() ? "--target" : !options.up.empty() ? "--up" : "--fovy";
      throw UsageError(fmt::format("{}: {}", flag, problem->reason));
    }

  if (report.default_lights_added) {  // they follow the camera the flags chose
    scene.lights.clear();
    if (!options.lights_given()) scene.lights = make_default_lights(camera);
  }
  for (const std::vector<double>& v : options.point_lights) {
    Light light;
    light.position = Vec4d(v[0], v[1], v[2], 1.0);
    light.color = read_color(v, 3, "--point-light");
    scene.lights.push_back(light);
  }
  for (const std::vector<double>& v : options.directional_lights) {
    Light light;
    if (Vec3d(v[0], v[1], v[2]) == Vec3d(0.0)) throw UsageError("--directional-light: direction is zero");
    light.position = Vec4d(v[0], v[1], v[2], 0.0);
    light.color = read_color(v, 3, "--directional-light");
    scene.lights.push_back(light);
  }
  if (!options.background.empty()) scene.settings.background = read_color(options.background, 0, "--background");
}

std::vector<std::string> scene_notices(const SceneOptions& options, const LoadReport& report, const Scene& scene) {
  std::vector<std::string> notices;
  for (const std::string& warning : report.warnings) notices.push_back("warning: " + warning);
  const bool framed = report.camera_framed && options.eye.empty() && options.target.empty();
  const bool lights = report.default_lights_added && !options.lights_given();
  if (framed || lights) {
    std::string made;
    if (framed) made = fmt::format("framed its bounding box looking along {} (--eye/--target to choose)", direction_text(report.view));
    if (lights)
      made += std::string(framed ? "; " : "") +
              "lit it with a key light above and behind the eye and a headlight (--point-light/--directional-light to choose)";
    notices.push_back(fmt::format("note: {} has no {}: {}", scene.source,
                                  framed && lights ? "camera or lights" : framed ? "camera" : "lights", made));
  }
  return notices;
}

void apply_image_overrides(const ImageOverrides& image, Scene& scene) {
  RenderSettings& settings = scene.settings;
  // One side given: the other (`other`) keeps the scene's aspect ratio, rounded to the nearest pixel.
  const auto follow = [](int given, int other_now, int given_now, const char* flag, const char* other) {
    const double side = std::max(1.0, std::round(double(given) * other_now / given_now));
    if (side > kMaxImageSide)
      throw UsageError(fmt::format("--{} {} at the scene's aspect ratio makes the {} {:.0f} pixels (at most {}); give "
                                   "--{} too", flag, given, other, side, kMaxImageSide, other));
    return int(side);
  };
  if (image.width && !image.height)
    settings.height = follow(*image.width, settings.height, settings.width, "width", "height");
  if (image.height && !image.width)
    settings.width = follow(*image.height, settings.width, settings.height, "height", "width");
  if (image.width) settings.width = *image.width;
  if (image.height) settings.height = *image.height;
  if (image.max_depth) settings.max_depth = *image.max_depth;
  if (image.display) settings.display.encoding = *image.display;
  if (image.exposure_ev) settings.display.exposure_ev = *image.exposure_ev;
  if (image.tonemap) settings.display.tonemap = *image.tonemap;
}

Scene load_scene_for_command(const std::string& path, const GltfOptions& gltf, const ImageOverrides& image,
                             const SceneOptions& options, LoadReport& report) {
  // --gltf-scene and --camera choose among what a glTF file holds; other formats have one of each.
  if ((gltf.scene || !gltf.camera.empty()) && !is_gltf_path(path))
    throw UsageError(fmt::format("{} applies to .gltf/.glb scenes only, not '{}'",
                                 gltf.scene && !gltf.camera.empty() ? "--gltf-scene and --camera each"
                                 : gltf.scene                       ? "--gltf-scene"
                                                                    : "--camera",
                                 path.empty() ? "<built-in default>" : path));
  Scene scene = path.empty() ? make_default_scene() : load_scene(path, gltf, &report);
  apply_image_overrides(image, scene);
  apply_scene_options(options, report, scene);
  validate_scene(scene);
  return scene;
}

}  // namespace rt
