#pragma once
// The delta mode's files, read and written in one place: measurements
// (`calbox.measurements/1`), results (`calbox.delta-result/1`) and probe heights (CSV x,y,z).
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

// CSV `x,y,z` per line (a header line starting with x and # comments are skipped): the nozzle's
// height over the bed when commanded to (x, y, 0).
std::vector<solve::ProbePoint> probe_from_csv(std::string_view text, const std::string& source);

}  // namespace calbox::modes
