#pragma once
// Moved to core (docs/design.md, "Layers"): the reference objects are also the recognition
// catalogue's built-in models. Kept for existing includers.
#include "sonar3d/core/reference_objects.hpp"
