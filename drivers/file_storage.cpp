#include "drivers/file_storage.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace calbox::drivers {
namespace {

std::runtime_error os_error(const std::string& what, const std::filesystem::path& p) {
    return std::runtime_error(what + " " + p.string() + ": " + std::strerror(errno));
}

class Fd {
  public:
    explicit Fd(int fd) : fd_(fd) {}
    Fd(const Fd&) = delete;
    Fd& operator=(const Fd&) = delete;
    ~Fd() {
        if (fd_ >= 0) ::close(fd_);
    }
    int get() const { return fd_; }
    int release() { return std::exchange(fd_, -1); }

  private:
    int fd_;
};

}  // namespace

FileStorage::FileStorage(std::filesystem::path directory) : directory_(std::move(directory)) {
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
    // Write a sibling, flush it to the medium, then rename over the old file: a power cut
    // leaves either the old contents or the new ones.
    auto temporary = path;
    temporary += ".tmp";
    Fd file(::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
    if (file.get() < 0) throw os_error("cannot create", temporary);
    std::size_t written = 0;
    while (written < contents.size()) {
        const ssize_t n = ::write(file.get(), contents.data() + written, contents.size() - written);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            const auto error = os_error("cannot write", temporary);
            ::unlink(temporary.c_str());
            throw error;
        }
        written += static_cast<std::size_t>(n);
    }
    if (::fsync(file.get()) != 0 || ::close(file.release()) != 0) {
        const auto error = os_error("cannot flush", temporary);
        ::unlink(temporary.c_str());
        throw error;
    }
    if (::rename(temporary.c_str(), path.c_str()) != 0) {
        const auto error = os_error("cannot replace", path);
        ::unlink(temporary.c_str());
        throw error;
    }
    Fd directory(::open(directory_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
    if (directory.get() >= 0) ::fsync(directory.get());
}

}  // namespace calbox::drivers
