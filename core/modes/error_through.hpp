#pragma once
// The machine's error as jobs sent through a kept correction meet it, worked out from a target
// made without the correction: what drift and "needs calibrating" ask of a mode whose
// correction the box keeps, so that a cycle is compared with the last correction's verified
// figure on the same footing (both the error through a correction in force), not the raw
// machine's error with the error left through the correction.
#include <vector>

#include "core/geometry/types.hpp"
#include "core/jobs/compensate.hpp"
#include "core/modes/goal.hpp"

namespace calbox::modes {

// `commanded_mm[i]` was sent as it is and landed `error_mm[i]` from it. Through `kept` a job's
// point p is commanded at c = kept(p) (held at the kept rectangle's edge beyond it, as jobs are)
// and lands at c + e(c): e(c) is the error seen at p moved by what `error_field` (the machine's
// error now, as this measurement's fit has it) changes between p and c, which matters where
// the correction moves points far (a router's millimetre: 0.005 mm of a 0.5 % scale error);
// without a field, the error seen at p. Those landings' rigid part (where the work lies, set by
// hand on the machine) is taken out as a verification's is. Throws std::invalid_argument for
// lists of different lengths or under three points.
ErrorFigures error_through(const std::vector<geometry::Point2>& commanded_mm,
                           const std::vector<geometry::Point2>& error_mm,
                           const jobs::KeptCorrection& kept,
                           const jobs::Correction& error_field = {});

}  // namespace calbox::modes
