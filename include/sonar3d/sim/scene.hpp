#pragma once
// Moved to core (docs/design.md, "Layers"): scenes are shared by every module that knows the CAD
// ground truth (eval, video, mapping, world), not only the simulator. Kept for existing includers.
#include "sonar3d/core/scene.hpp"
