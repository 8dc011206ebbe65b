#pragma once
// print.json: what a job really made on the twin, stroke by stroke (schema "calbox.print/1").
#include <string>

#include "board/sim/gcode_runner.hpp"

namespace calbox::sim {

struct PrintRecord {
    std::string scenario;
    std::string job;
    std::string machine_kind;
    JobResult result;
};

std::string print_to_json(const PrintRecord& record);
// Throws std::runtime_error naming what is missing or malformed.
PrintRecord print_from_json(const std::string& text);

}  // namespace calbox::sim
