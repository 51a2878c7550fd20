#pragma once
// rt view: the render shown in a window while it runs (GLFW and OpenGL 3.3), progressively.

#include <string>

#include "rt/accel/accel.h"
#include "rt/render/render.h"

namespace rt {

struct ViewOptions {
  // Threads, samples per pixel, ray offsets and effects of every render; the viewer sets the
  // region, sample index, callbacks and cancel flag itself.
  RenderOptions render;
  std::string save_path;        // where the S key writes the image shown (write_image)
  std::string screenshot_path;  // non-empty: once the render is complete, read the window's pixels back into this file
  bool exit_when_done = false;  // close the window once the render is complete (and the screenshot written)
  std::string scene_name;       // for the title bar
  bool quiet = false;           // no summary lines on stderr
};

// Throws RuntimeError, with one line that points to `rt render`, unless a window can be opened
// (an X11 display GLFW can reach). Leaves GLFW initialised for run_viewer.
void check_display();

// Opens a window of the scene's image size (scaled down to fit the screen) and renders into it
// until the window is closed: a preview at 1/8 resolution, then the full image tile by tile, then,
// with samples_per_pixel > 1, one sample more per pass, averaged. Mouse drag orbits the camera
// around its target, the wheel zooms, R re-renders, S saves, Q or Esc quits; any camera move
// restarts the render. When complete, the pixels shown are the ones `rt render` writes for the
// same camera. Returns the exit status: 0, or 1 when a render or the screenshot failed or the
// window was closed before a requested screenshot could be taken.
int run_viewer(const Scene& scene, const FlatScene& flat, const Accel& accel, const ViewOptions& options);

}  // namespace rt
