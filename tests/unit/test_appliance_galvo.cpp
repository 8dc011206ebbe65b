// The appliance with a galvo scanner (its table corrected through the box and reverted) and
// with a PLC reading each mode's own pass bit.
#include "tests/unit/appliance_rig.hpp"

TEST_GROUP(ApplianceGalvo){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

TEST(ApplianceGalvo, a_scanner_is_corrected_through_the_boxs_table_and_reverted) {
    const fs::path dir = fresh_dir("galvo");
    Rig rig(dir, (fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios/galvo_small.toml").string(), {});
    const auto identity = [](sim::Vec2 p) { return p; };
    const double half = 55.0 * 30 / 31;
    const auto before = rig.board.bench->judge_galvo_scanner(identity, {-half, -half, half, half});
    rig.run_cycle();
    rig.check_cycles_completed(1);
    const auto& report = rig.cycle.report();
    const auto* galvo = dynamic_cast<const firmware::GalvoCycleMode*>(&rig.cycle.mode());
    CHECK(galvo != nullptr && galvo->solution().has_value());
    CHECK(report.applied);
    // The box's own figures: the grid as burned, and through the table.
    CHECK(report.measured->rms_mm > 0.05);
    CHECK_TEXT(report.verified->rms_mm <= 0.004, std::to_string(report.verified->rms_mm).c_str());
    CHECK(report.verified->max_mm <= 0.015);
    // What the review promised is what the verification then measured, within a factor of 1.5
    // either way (it once promised 0.0001 mm RMS, a seventh of the 0.0007 measured).
    const double predicted = galvo->solution()->predicted_rms_mm;
    UT_PRINT(("galvo review predicted " + std::to_string(predicted) + " mm RMS, verified " +
              std::to_string(report.verified->rms_mm))
                 .c_str());
    CHECK(predicted <= 1.5 * report.verified->rms_mm);
    CHECK(report.verified->rms_mm <= 1.5 * predicted);
    // The twin judges the table the box keeps, on a fresh grid.
    const auto kept = rig.data.read_file(firmware::kGalvoTableFile);
    CHECK(kept.has_value());
    // The file the web page serves with the records is the one the table is kept in.
    CHECK(rig.cycle.mode().kept_files() == std::vector<std::string>{firmware::kGalvoTableFile});
    // What a controller reads over Modbus: that table, under the key a map file moves it by, in
    // as many registers as the mode declares (the PLC's map checks overlaps with that count).
    const auto for_controller = rig.cycle.mode().result(true);
    CHECK_EQUAL(firmware::GalvoCycleMode::result_table().key, for_controller.table_key);
    CHECK_EQUAL(firmware::GalvoCycleMode::result_table().registers,
                2 * static_cast<int>(for_controller.table.size()));
    const auto table = modes::galvo_result_from_json(*kept, "kept").fit.table;
    const auto after = rig.board.bench->judge_galvo_scanner(
        [&table](sim::Vec2 p) {
            const auto c = table.command_for({p.x, p.y});
            return sim::Vec2{c.x, c.y};
        },
        {table.min_x_mm, table.min_y_mm, table.max_x_mm, table.max_y_mm});
    UT_PRINT(("galvo on the box: before " + std::to_string(before.mean_mm) + " mm mean, after " +
              std::to_string(after.mean_mm) + " mean " + std::to_string(after.max_mm) +
              " worst; the box verified " + std::to_string(report.verified->rms_mm) + " RMS")
                 .c_str());
    // The goal is 0.008 mean and 0.03 worst; the README claims 0.002 and 0.008.
    CHECK(before.mean_mm > 0.05);
    CHECK(after.mean_mm <= 0.002);
    CHECK(after.max_mm <= 0.008);
    // Two jobs went: the grid, then the grid through the table: the same lines but the moves.
    const auto sent = rig.transcript();
    const auto count = [&sent](const std::string& word) {
        return std::count_if(sent.begin(), sent.end(), [&word](const std::string& l) {
            return l.find(word) != std::string::npos;
        });
    };
    // grbl's plain lines: each job opens with its own G21, nothing numbered or checksummed.
    CHECK_EQUAL(2, std::count(sent.begin(), sent.end(), "G21"));
    CHECK_EQUAL(0, count("M110"));
    CHECK_EQUAL(0, count("*"));
    CHECK(count("M3 S") > 1900);    // every mark's beam switched on, twice
    CHECK_EQUAL(0, count("M665"));  // a galvo's geometry is not a printer's settings
    CHECK(rig.data.read_file("cycle-0001-table.csv").has_value());
    const auto verified = modes::galvo_result_from_json(
        *rig.data.read_file("cycle-0001-verify-result.json"), "verify-result.json");
    CHECK_EQUAL(2, verified.pass);
    DOUBLES_EQUAL(report.verified->rms_mm, verified.fit.before.rms_mm, 1e-12);
    CHECK_EQUAL(std::string(firmware::kNoGalvoTable),
                *rig.data.read_file("cycle-0001-backup-table.json"));

    // Issue "Figures and drawings that mean what they say": a second cycle on the scanner as its
    // table left it reads no drift and no need, though the raw grid is as far off as ever (the
    // box once compared that raw error with the error verified through the table). Its owner
    // only looks: cancelled at review, nothing sent.
    firmware::BoxNews news(rig.data, "test", {});
    news.cycle_ended(rig.cycle, true, 1'700'000'000);
    const auto told = rig.cycle.subscribe(
        {{},
         {},
         [&](bool completed) { news.cycle_ended(rig.cycle, completed, 1'700'000'600); },
         {},
         {}});
    // The owner only looks: each cycle below is cancelled at review (a long press).
    const auto cancel_at_review = [&rig](firmware::Prompt p) {
        if (p != firmware::Prompt::review) return false;
        rig.board.lines->press(2000ms);
        return true;
    };
    rig.intercept = cancel_at_review;
    rig.ended = 0;
    rig.run_cycle();
    rig.intercept = nullptr;
    rig.check_cycles_completed(1);
    const auto& again = rig.cycle.report();
    UT_PRINT(("galvo, second cycle: raw " + number_text("%.4f", *again.measured->mean_mm) +
              " mm mean, through the table " + number_text("%.4f", *again.in_force->mean_mm) +
              " (the twin's truth " + number_text("%.4f", after.mean_mm) + "), drift " +
              number_text("%.4f", news.drift_mm().value_or(-1)))
                 .c_str());
    CHECK(*again.measured->mean_mm > 0.05);
    CHECK(std::abs(*again.in_force->mean_mm - after.mean_mm) < 0.002);
    CHECK(std::abs(*news.drift_mm()) < 0.003);
    CHECK_FALSE(*news.needs_calibration());
    CHECK_EQUAL(*kept, *rig.data.read_file(firmware::kGalvoTableFile));  // nothing applied

    // Then the x mirror's gain drifts by 0.1 % (0.055 mm at the field's edges): a third cycle,
    // again only looked at, reads that as drift, as the twin's truth has it through the table.
    // (A head turned on its mount moves the whole field, which each measurement places anew.)
    rig.board.bench->change_machine([](sim::Scenario& s) { s.galvo_truth.gain_x += 0.001; });
    const auto changed = rig.board.bench->judge_galvo_scanner(
        [&table](sim::Vec2 p) {
            const auto c = table.command_for({p.x, p.y});
            return sim::Vec2{c.x, c.y};
        },
        {table.min_x_mm, table.min_y_mm, table.max_x_mm, table.max_y_mm});
    rig.intercept = cancel_at_review;
    rig.ended = 0;
    rig.run_cycle();
    rig.intercept = nullptr;
    rig.check_cycles_completed(1);
    UT_PRINT(("galvo, third cycle (gain drifted): through the table " +
              number_text("%.4f", *rig.cycle.report().in_force->mean_mm) + " (the twin's truth " +
              number_text("%.4f", changed.mean_mm) + "), drift " +
              number_text("%.4f", news.drift_mm().value_or(-1)))
                 .c_str());
    CHECK(changed.mean_mm > 0.015);
    CHECK(std::abs(*rig.cycle.report().in_force->mean_mm - changed.mean_mm) < 0.005);
    CHECK(std::abs(*news.drift_mm() - changed.mean_mm) < 0.005);

    // Revert puts back what was in force before: no table.
    const std::size_t sent_before_revert = rig.transcript().size();
    CHECK_EQUAL(std::string(), rig.cycle.revert());
    rig.run_until([&rig] { return rig.cycle.state() == firmware::CycleState::idle; });
    CHECK_EQUAL(std::string(firmware::kNoGalvoTable),
                *rig.data.read_file(firmware::kGalvoTableFile));
    CHECK_EQUAL(sent_before_revert, rig.transcript().size());
}

// Issue "One shape for every mode": the PLC's pass bit is each mode's own goal on the box's own
// verification, not the delta goal for every machine.
namespace {

// The box's registers as a PLC would read them.
class PlcRegisters final : public hal::RegisterServer {
  public:
    std::vector<bool> inputs = std::vector<bool>(firmware::plc::kDiscreteInputCount, false);
    std::map<int, std::uint16_t> registers;
    int written_fd() const override { return -1; }
    std::vector<int> take_coils_set() override { return {}; }
    void set_discrete_inputs(int first, const std::vector<bool>& values) override {
        for (std::size_t i = 0; i < values.size(); ++i)
            inputs.at(static_cast<std::size_t>(first) + i) = values[i];
    }
    void set_input_registers(int first, std::span<const std::uint16_t> values) override {
        for (std::size_t i = 0; i < values.size(); ++i)
            registers[first + static_cast<int>(i)] = values[i];
    }
    double result(const std::string& name) const {
        const auto& names = firmware::result_value_names();
        const auto at = std::find(names.begin(), names.end(), name) - names.begin();
        const int address = firmware::plc::kResultBlockRegister + 2 * static_cast<int>(at);
        return models::unpack_float({registers.at(address), registers.at(address + 1)},
                                    models::WordOrder::abcd);
    }
};

struct PlcRig {
    Rig rig;
    PlcRegisters registers;
    firmware::PlcServer plc{registers, rig.cycle, models::WordOrder::abcd,
                            [](const std::string&) {}};
    explicit PlcRig(const std::string& scenario)
        : rig(fresh_dir("plc-" + fs::path(scenario).stem().string()),
              (fs::path(CALBOX_SOURCE_DIR) / scenario).string(), {}) {
        rig.run_cycle();
        rig.check_cycles_completed(1);
        plc.publish();
        CHECK(registers.inputs[firmware::plc::kDoneInput]);
    }
};

}  // namespace

TEST_GROUP(AppliancePlc){void setup() override{mock().ignoreOtherCalls();
}
}
;

// The router's own figures: 0.025 mm mean (0.027 RMS, 0.065 worst) through the model, from 1.23
// before: under 0.05 and 98 % less. The delta goal (RMS <= 0.01) would have read fail.
TEST(AppliancePlc, a_router_meeting_its_goal_reads_pass) {
    PlcRig r("tests/scenarios/planar_small.toml");
    const auto& report = r.rig.cycle.report();
    UT_PRINT(("router verified " + std::to_string(*report.verified->mean_mm) + " mm mean, " +
              std::to_string(report.verified->rms_mm) + " RMS, from " +
              std::to_string(*report.measured->mean_mm))
                 .c_str());
    CHECK(*report.verified->mean_mm < 0.05);
    CHECK(*report.verified->mean_mm < 0.05 * *report.measured->mean_mm);
    CHECK(report.verified->rms_mm > 0.01);
    CHECK(r.registers.inputs[firmware::plc::kPassInput]);
    CHECK(r.rig.cycle.goal_met());
    DOUBLES_EQUAL(report.verified->rms_mm, r.registers.result("verified_xy_rms_mm"), 1e-5);
    CHECK(std::isnan(r.registers.result("diagonal_rod_mm")));  // a router has no rods
    // grbl reads plain lines: nothing numbered, checksummed or opened by M110 went to it (the
    // twin answers those as grbl does, error:1 and error:20, and the cycle would have failed).
    const auto sent = r.rig.transcript();
    CHECK(sent.size() > 100);
    for (const auto& line : sent)
        CHECK_TEXT(line.find('*') == std::string::npos && line.find("M110") == std::string::npos,
                   line.c_str());
}

// Under a coarse, noisy camera the box measures the grid through its table at 0.012 mm mean:
// it cannot confirm the galvo goal (0.008), and says so.
TEST(AppliancePlc, a_galvo_missing_its_goal_reads_fail) {
    PlcRig r("tests/scenarios/galvo_coarse.toml");
    const auto& report = r.rig.cycle.report();
    UT_PRINT(("galvo verified " + std::to_string(*report.verified->mean_mm) + " mm mean, " +
              std::to_string(report.verified->max_mm) + " worst")
                 .c_str());
    CHECK(report.applied);
    CHECK(*report.verified->mean_mm > 0.008);
    CHECK_FALSE(r.registers.inputs[firmware::plc::kPassInput]);
    CHECK_FALSE(r.rig.cycle.goal_met());
    STRCMP_CONTAINS("goal (mean <= 0.0080 mm, worst <= 0.0300 mm): not met",
                    [&r] {
                        firmware::BoxConfig config;
                        firmware::LogBook log_book;
                        firmware::Console console({r.rig.cycle,
                                                   config,
                                                   r.rig.data,
                                                   "calbox.toml",
                                                   r.rig.data,
                                                   log_book,
                                                   "test",
                                                   {},
                                                   {}});
                        return console.reply_to("last");
                    }()
                        .c_str());
}
