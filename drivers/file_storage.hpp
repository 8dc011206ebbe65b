#pragma once
#include <filesystem>

#include "drivers/durable_file.hpp"
#include "hal/storage.hpp"

namespace calbox::drivers {

// Files under one directory; names may not leave it.
class FileStorage final : public hal::Storage {
  public:
    explicit FileStorage(std::filesystem::path directory,
                         FileSystemCalls& fs = posix_file_system());
    std::optional<std::string> read_file(const std::string& name) override;
    void replace_file(const std::string& name, const std::string& contents) override;
    void replace_private_file(const std::string& name, const std::string& contents) override;
    std::vector<Entry> list_files() override;
    void remove_file(const std::string& name) override;
    const std::filesystem::path& directory() const { return directory_; }

  private:
    std::filesystem::path path_of(const std::string& name) const;
    std::filesystem::path directory_;
    FileSystemCalls& fs_;
};

}  // namespace calbox::drivers
