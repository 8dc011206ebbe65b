#pragma once
// Whole-file persistence: a reader sees the old file or the new one, never a mix.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace calbox::hal {

class Storage {
  public:
    virtual ~Storage() = default;
    // The file's contents, or empty when it does not exist; throws std::runtime_error otherwise.
    virtual std::optional<std::string> read_file(const std::string& name) = 0;
    // Replaces the whole file atomically; throws std::runtime_error and leaves the old file
    // untouched on failure.
    virtual void replace_file(const std::string& name, const std::string& contents) = 0;
    // As replace_file, readable by the box's own user alone from its first byte (a key).
    virtual void replace_private_file(const std::string& name, const std::string& contents) = 0;
    // The files there, by name, with their sizes (records are pruned by both).
    struct Entry {
        std::string name;
        std::uintmax_t size_bytes = 0;
    };
    virtual std::vector<Entry> list_files() = 0;
    // Removes the file if it exists; throws std::runtime_error when it cannot.
    virtual void remove_file(const std::string& name) = 0;
};

}  // namespace calbox::hal
