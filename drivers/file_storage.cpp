#include "drivers/file_storage.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace calbox::drivers {

FileStorage::FileStorage(std::filesystem::path directory, FileSystemCalls& fs)
    : directory_(std::move(directory)), fs_(fs) {
    if (!std::filesystem::is_directory(directory_)) {
        throw std::runtime_error("storage directory does not exist: " + directory_.string());
    }
}

std::filesystem::path FileStorage::path_of(const std::string& name) const {
    const std::filesystem::path relative(name);
    if (name.empty() || relative.is_absolute() || relative.filename() != relative) {
        throw std::invalid_argument("storage name must be a plain file name: '" + name + "'");
    }
    return directory_ / relative;
}

std::optional<std::string> FileStorage::read_file(const std::string& name) {
    const auto path = path_of(name);
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        if (!std::filesystem::exists(path)) return std::nullopt;
        throw os_error("cannot read", path);
    }
    std::ostringstream contents;
    contents << in.rdbuf();
    return contents.str();
}

void FileStorage::replace_file(const std::string& name, const std::string& contents) {
    const auto path = path_of(name);
    replace_file_durably(fs_, directory_, path.filename().string(), contents);
}

void FileStorage::replace_private_file(const std::string& name, const std::string& contents) {
    const auto path = path_of(name);
    replace_file_durably(fs_, directory_, path.filename().string(), contents,
                         FileAccess::owner_only);
}

std::vector<hal::Storage::Entry> FileStorage::list_files() {
    std::vector<Entry> files;
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(directory_, ec)) {
        std::error_code size_ec;
        if (!entry.is_regular_file(size_ec)) continue;
        const auto size = entry.file_size(size_ec);
        if (size_ec) continue;  // removed meanwhile
        files.push_back({entry.path().filename().string(), size});
    }
    if (ec) throw std::runtime_error("cannot list " + directory_.string() + ": " + ec.message());
    return files;
}

void FileStorage::remove_file(const std::string& name) {
    const auto path = path_of(name);
    if (::unlink(path.c_str()) != 0 && errno != ENOENT) throw os_error("cannot remove", path);
}

}  // namespace calbox::drivers
