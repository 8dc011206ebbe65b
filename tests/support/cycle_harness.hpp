#pragma once
// One machine through its mode's cycle on the twin, as the box runs it: the twin makes the
// target and the camera photographs it, the box measures it, solves and the correction is put in
// force, pass after pass for as long as the mode asks; then the twin judges the machine in its
// truth. Each mode's test gives the steps as a case (test_delta_cycle, test_galvo, test_planar);
// the loop is written once, here.
namespace calbox::test {

// Case: `make_target(pass)` -> the photo of what the machine made; `measure(photo, pass)` -> the
// mode's measurement; `solve_and_correct(measured, pass)` -> true to make the target again as
// the next pass; `judge()` -> the test's figures, in the twin's truth.
template <class Case>
auto run_mode_cycle(Case& c) {
    for (int pass = 1;; ++pass) {
        const auto photo = c.make_target(pass);
        const auto measured = c.measure(photo, pass);
        if (!c.solve_and_correct(measured, pass)) break;
    }
    return c.judge();
}

}  // namespace calbox::test
