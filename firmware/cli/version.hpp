#pragma once
// The firmware's version: the project's, then "+git.<commits>.<hash>" when built from a git
// checkout (".dirty" for uncommitted changes). Written at build time (cmake/version.cmake), so
// `calbox --version`, the console's `version`, /metrics and MQTT discovery say the build they are.
namespace calbox {
const char* build_version();
}
