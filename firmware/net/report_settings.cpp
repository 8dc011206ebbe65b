// The report's table of the configuration: [report], when the box says the machine needs
// calibrating.
#include <string>

#include "firmware/net/box_news.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::decimal;
using setting_text::number;

const SettingKey<ReportSettings> kReportKeys[] = {
    {{"needs_calibration_mm",
      K::number,
      "mm",
      0.001,
      10,
      {},
      false,
      "a cycle's error as jobs met it (its mean, a delta's RMS; through the correction the box "
      "keeps, for a galvo or a router) past this: the machine needs calibrating (the page, MQTT, "
      "/metrics)"},
     [](const ReportSettings& s) { return number(s.needs_calibration_mm); },
     [](ReportSettings& s, const KeyInfo& k, std::string_view t) {
         s.needs_calibration_mm = decimal(k, t);
     }},
};

}  // namespace

SettingsTable<ReportSettings> report_settings_table() {
    return {"report", kReportKeys};
}

}  // namespace calbox::firmware
