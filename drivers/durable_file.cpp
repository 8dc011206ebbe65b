#include "drivers/durable_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace calbox::drivers {

std::runtime_error os_error(const std::string& what, const std::filesystem::path& p) {
    return std::runtime_error(what + " " + p.string() + ": " + std::strerror(errno));
}

namespace {

class PosixFileSystem final : public FileSystemCalls {
  public:
    int create_truncated(const std::filesystem::path& path, FileAccess access) override {
        const mode_t mode = access == FileAccess::owner_only ? 0600 : 0644;
        const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
        if (fd < 0) throw os_error("cannot create", path);
        // A sibling left by an earlier cut keeps its own mode through open(): set it.
        if (::fchmod(fd, mode) != 0) {
            const auto error = os_error("cannot restrict", path);
            ::close(fd);
            throw error;
        }
        return fd;
    }
    void write_all(int fd, std::string_view bytes) override {
        std::size_t written = 0;
        while (written < bytes.size()) {
            const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
            if (n < 0 && errno == EINTR) continue;
            if (n < 0) throw os_error("cannot write", fd_path(fd));
            if (n == 0) {
                errno = ENOSPC;
                throw os_error("cannot write", fd_path(fd));
            }
            written += static_cast<std::size_t>(n);
        }
    }
    void flush(int fd) override {
        if (::fsync(fd) != 0) throw os_error("cannot flush", fd_path(fd));
    }
    void close(int fd) override {
        if (::close(fd) != 0) throw os_error("cannot close", fd_path(fd));
    }
    void rename(const std::filesystem::path& from, const std::filesystem::path& to) override {
        if (::rename(from.c_str(), to.c_str()) != 0) throw os_error("cannot replace", to);
    }
    void flush_directory(const std::filesystem::path& directory) override {
        const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (fd < 0) throw os_error("cannot open the directory", directory);
        const int synced = ::fsync(fd);
        const int saved_errno = errno;
        ::close(fd);
        errno = saved_errno;
        if (synced != 0) throw os_error("cannot flush the directory", directory);
    }
    void remove(const std::filesystem::path& path) noexcept override { ::unlink(path.c_str()); }

  private:
    // For messages only: the file a descriptor names.
    static std::filesystem::path fd_path(int fd) {
        std::error_code ec;
        auto p = std::filesystem::read_symlink("/proc/self/fd/" + std::to_string(fd), ec);
        return ec ? std::filesystem::path("descriptor " + std::to_string(fd)) : p;
    }
};

}  // namespace

FileSystemCalls& posix_file_system() {
    static PosixFileSystem fs;
    return fs;
}

void replace_file_durably(FileSystemCalls& fs, const std::filesystem::path& directory,
                          const std::string& name, std::string_view contents, FileAccess access) {
    const auto path = directory / name;
    auto sibling = path;
    sibling += ".tmp";
    const int handle = fs.create_truncated(sibling, access);
    try {
        try {
            fs.write_all(handle, contents);
            fs.flush(handle);
        } catch (...) {
            try {
                fs.close(handle);
            } catch (const std::runtime_error&) {  // the first error is the one to tell
            }
            throw;
        }
        fs.close(handle);
        fs.rename(sibling, path);
    } catch (...) {
        fs.remove(sibling);
        throw;
    }
    // The new contents are in place; the directory's flush makes the rename survive a power cut.
    fs.flush_directory(directory);
}

}  // namespace calbox::drivers
