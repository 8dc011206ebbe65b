#pragma once
// Strict reading of TOML tables for calbox's files: every key is checked for type and range,
// and a key nobody read is an error, so a typo never becomes a silent default. Include only
// from .cpp files (it brings in toml++).
#include <toml++/toml.h>

#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "core/models/machine_file.hpp"

namespace calbox::models {

class TomlReader {
  public:
    TomlReader(std::string file, const toml::table& table, std::string section)
        : file_(std::move(file)), table_(table), section_(std::move(section)) {}

    [[noreturn]] void fail(const std::string& key, const std::string& why) const {
        throw MachineFileError(file_ + ": " + (section_.empty() ? "" : "[" + section_ + "] ") +
                               key + ": " + why);
    }
    void number(const char* key, double& field, double min, double max);
    void number(const char* key, std::optional<double>& field, double min, double max);
    void integer(const char* key, int& field, int min, int max);
    void boolean(const char* key, bool& field);
    void text(const char* key, std::string& field, const std::set<std::string>& allowed);
    void text(const char* key, std::optional<std::string>& field);
    std::vector<double> numbers(const char* key, std::size_t min_count, std::size_t max_count);
    void triple(const char* key, std::array<double, 3>& field);
    // Every key must have been read; sub-tables are left to their own readers.
    void finish() const;

  private:
    const toml::node* find(const char* key);
    std::string file_;
    const toml::table& table_;
    std::string section_;
    std::set<std::string> seen_;
};

const toml::table* subtable(const std::string& file, const toml::table& parent, const char* name);
toml::table parse_toml(std::string_view text,
                       const std::string& source);  // throws MachineFileError
void read_delta_settings(const std::string& file, const toml::table& table,
                         const std::string& section, DeltaSettings& delta);
MachineFile read_machine_tables(const std::string& file, const toml::table& root,
                                std::initializer_list<std::string_view> other_sections);

}  // namespace calbox::models
