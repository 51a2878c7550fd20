#pragma once
// Loader for the CSE167x / CS184.1x ray-tracer scene format (".test" files): one command per
// line, OpenGL-style transform stack, material and attenuation as current state captured by
// each primitive. See docs/scene-formats.md for the command-by-command mapping onto the scene
// graph.

#include <string>

#include "rt/scene/scene.h"

namespace rt {

// Parses the text of a .test scene; `path` names the source in messages. The result is
// validated. Throws InputError "PATH:LINE: reason" for the first problem found (unknown command,
// wrong parameter count, non-numeric or non-finite number, `size` not first, a stack underflow,
// vertex indices out of range, a bad camera, ...).
Scene parse_test_scene(const std::string& text, const std::string& path);

// Reads and parses a .test file (see parse_test_scene). Throws InputError if it cannot be read.
Scene load_test_scene(const std::string& path);

}  // namespace rt
