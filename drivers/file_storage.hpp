#pragma once
#include <filesystem>

#include "hal/storage.hpp"

namespace calbox::drivers {

// Files under one directory; names may not leave it.
class FileStorage final : public hal::Storage {
  public:
    explicit FileStorage(std::filesystem::path directory);
    std::optional<std::string> read_file(const std::string& name) override;
    void replace_file(const std::string& name, const std::string& contents) override;

  private:
    std::filesystem::path path_of(const std::string& name) const;
    std::filesystem::path directory_;
};

}  // namespace calbox::drivers
