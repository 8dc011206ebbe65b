#include "core/modes/goal.hpp"

#include "core/number_text.hpp"

namespace calbox::modes {
namespace {

std::string mm(double v) {
    return number_text("%.4f", v) + " mm";
}

}  // namespace

std::string ModeGoal::shortfall(const ErrorFigures& before, const ErrorFigures& after) const {
    if (rms_at_most_mm && !(after.rms_mm <= *rms_at_most_mm))
        return "RMS " + mm(after.rms_mm) + " (goal <= " + mm(*rms_at_most_mm) + ")";
    if (max_at_most_mm && !(after.max_mm <= *max_at_most_mm))
        return "worst " + mm(after.max_mm) + " (goal <= " + mm(*max_at_most_mm) + ")";
    if (mean_at_most_mm || mean_under_mm || reduction_at_least)
        return mean_shortfall(before, after);
    return {};
}

std::string ModeGoal::mean_shortfall(const ErrorFigures& before, const ErrorFigures& after) const {
    if (!after.mean_mm) return "no mean error to judge";
    const double mean = *after.mean_mm;
    if (mean_at_most_mm && !(mean <= *mean_at_most_mm))
        return "mean " + mm(mean) + " (goal <= " + mm(*mean_at_most_mm) + ")";
    if (mean_under_mm && !(mean < *mean_under_mm))
        return "mean " + mm(mean) + " (goal under " + mm(*mean_under_mm) + ")";
    // A machine already within the bar before the cycle (one whose own settings carry an
    // earlier correction) is judged by the bar alone: a share of what is left is noise.
    if (!reduction_at_least || (before.mean_mm && mean_within_bar(*before.mean_mm))) return {};
    if (!before.mean_mm || !(*before.mean_mm > 0)) return "no mean error before to judge";
    const double reduction = 1 - mean / *before.mean_mm;
    if (!(reduction >= *reduction_at_least))
        return number_text("%.1f", 100 * reduction) + " % less (goal " +
               number_text("%.0f", 100 * *reduction_at_least) + " %)";
    return {};
}

bool ModeGoal::mean_within_bar(double mean_mm) const {
    return (!mean_at_most_mm || mean_mm <= *mean_at_most_mm) &&
           (!mean_under_mm || mean_mm < *mean_under_mm) && (mean_at_most_mm || mean_under_mm);
}

std::string ModeGoal::describe() const {
    std::string out;
    auto add = [&out](const std::string& part) { out += (out.empty() ? "" : ", ") + part; };
    if (rms_at_most_mm) add("RMS <= " + mm(*rms_at_most_mm));
    if (mean_at_most_mm) add("mean <= " + mm(*mean_at_most_mm));
    if (mean_under_mm) add("mean under " + mm(*mean_under_mm));
    if (max_at_most_mm) add("worst <= " + mm(*max_at_most_mm));
    if (reduction_at_least) add(number_text("%.0f", 100 * *reduction_at_least) + " % less");
    return out;
}

ModeGoal delta_goal() {
    ModeGoal g;
    g.mode = "delta";
    g.rms_at_most_mm = 0.01;
    g.max_at_most_mm = 0.03;
    return g;
}

ModeGoal galvo_goal() {
    ModeGoal g;
    g.mode = "galvo";
    g.mean_at_most_mm = 0.008;
    g.max_at_most_mm = 0.03;
    return g;
}

ModeGoal planar_goal() {
    ModeGoal g;
    g.mode = "planar";
    g.mean_under_mm = 0.05;
    g.reduction_at_least = 0.95;
    return g;
}

}  // namespace calbox::modes
