// The interactive window of tinstream-viewer: GLFW + Dear ImGui.
#pragma once

#include "tinstream/client/viewer.hpp"

namespace tinstream::client {

// Opens a window (needs a display), streams and draws until it is closed. Returns the process
// exit status (0; 2 bad input; 1 no window or no OpenGL 3.3).
int run_window(const ViewerOptions& options);

}  // namespace tinstream::client
