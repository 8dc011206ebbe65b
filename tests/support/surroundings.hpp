#pragma once
// The work (a drilled sheet, a marked plate) on a rectangle of the bed, and what the camera sees
// around it: the machine's dark bed, a grey floor, a white table.
#include "board/sim/scenes.hpp"

namespace calbox::test {

struct WorkOnBed {
    double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
    double surroundings_albedo = 0.06;
};

class SurroundedScene final : public sim::Scene {
  public:
    SurroundedScene(const sim::Scene& work, const WorkOnBed& on_bed)
        : work_(work), on_bed_(on_bed) {}
    double albedo(const sim::Footprint& f) const override {
        const bool on_work = f.centre_mm.x >= on_bed_.min_x_mm &&
                             f.centre_mm.x <= on_bed_.max_x_mm &&
                             f.centre_mm.y >= on_bed_.min_y_mm && f.centre_mm.y <= on_bed_.max_y_mm;
        return on_work ? work_.albedo(f) : on_bed_.surroundings_albedo;
    }

  private:
    const sim::Scene& work_;
    WorkOnBed on_bed_;
};

}  // namespace calbox::test
