#pragma once
// The delta mode's files, read and written in one place: measurements
// (`calbox.measurements/1`), results (`calbox.delta-result/1`); probe heights are delta_probe's.
// Text in, text out: the caller does the file I/O.
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/modes/delta.hpp"
#include "core/modes/record_error.hpp"

namespace calbox::modes {

std::string measurements_to_json(const DeltaMeasurementsRecord& record);
// `source` names the text in messages; throws RecordError with one line.
DeltaMeasurementsRecord measurements_from_json(std::string_view text, const std::string& source);

std::string result_to_json(const DeltaSolution& solution);
DeltaSolution result_from_json(std::string_view text, const std::string& source);

}  // namespace calbox::modes
