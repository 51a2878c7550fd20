#pragma once
// Camera, light and background flags shared by `rt render` and `rt info`: they supply what a
// format lacks (OBJ has no camera or lights) or override what a scene file says.

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rt/core/error.h"
#include "rt/io/load_scene.h"
#include "rt/scene/scene.h"

namespace CLI {
class App;
}

namespace rt {

// Values of the flags as parsed; empty vectors and nullopt mean "not given".
struct SceneOptions {
  std::vector<double> eye, target, up;  // 3 values each (the last occurrence counts)
  std::optional<double> fovy;           // degrees, in (0, 180)
  std::vector<std::vector<double>> point_lights;        // X Y Z R G B each
  std::vector<std::vector<double>> directional_lights;  // X Y Z (towards the light) R G B each
  std::vector<double> background;                       // R G B

  bool camera_given() const { return !eye.empty() || !target.empty() || !up.empty() || fovy.has_value(); }
  bool lights_given() const { return !point_lights.empty() || !directional_lights.empty(); }
};

// Adds --eye, --target, --up, --fovy, --point-light (repeatable), --directional-light
// (repeatable) and --background to `app`. Parsing rejects wrong counts, non-numbers, non-finite
// numbers and a fovy outside (0, 180).
void add_scene_options(CLI::App& app, SceneOptions& options);

// Applies the flags to a loaded scene whose settings (image size) are final. A camera the loader
// framed (report.camera_framed) is framed again for the final aspect ratio and --fovy; then
// every given camera field replaces the scene's. Light flags replace a loader's headlight and add
// to a file's own lights; without them a headlight follows the final eye. Throws UsageError naming
// the flag when a colour is negative, a direction zero or the resulting camera unusable.
void apply_scene_options(const SceneOptions& options, const LoadReport& report, Scene& scene);

// Image settings the command line overrides (--width, --height, --max-depth, --display,
// --exposure, --tonemap); nullopt: the scene's.
struct ImageOverrides {
  std::optional<int> width, height, max_depth;
  std::optional<DisplayEncoding> display;
  std::optional<double> exposure_ev;
  std::optional<ToneMap> tonemap;
};

// Applies the overrides to a loaded scene. With only one of width and height given, the other
// follows the scene's aspect ratio (rounded, at least 1 pixel); UsageError if it would exceed
// kMaxImageSide.
void apply_image_overrides(const ImageOverrides& image, Scene& scene);

// A scene as the commands load it: the file at `path` (empty: the built-in default scene), the
// image overrides, then the scene flags (apply_scene_options), validated. Throws UsageError when
// --gltf-scene or --camera is given for a format other than glTF, InputError on bad input.
Scene load_scene_for_command(const std::string& path, const GltfOptions& gltf, const ImageOverrides& image,
                             const SceneOptions& options, LoadReport& report);

// Lines for stderr (without the "rt: " prefix) telling what the loader warned about and what was
// made up for the file after the flags were applied: "warning: ..." and "note: ...".
std::vector<std::string> scene_notices(const SceneOptions& options, const LoadReport& report, const Scene& scene);

}  // namespace rt
