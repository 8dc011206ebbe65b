#pragma once
// Replacing a whole file so that a power cut at any moment leaves the old contents or the new
// ones, never a mix or nothing: write a sibling, flush it, rename it over the old file, flush the
// directory (without the last step the rename itself may be lost, and a save that returned
// would come back as the old file). The calls go through FileSystemCalls so that a test can cut
// the power between any two of them.
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

namespace calbox::drivers {

// Who may read a file the box writes: anyone (its records), or its own user alone (a key).
enum class FileAccess { shared, owner_only };

class FileSystemCalls {
  public:
    virtual ~FileSystemCalls() = default;
    // Each throws std::runtime_error naming the path and the system's reason.
    // A handle; an owner_only file is mode 0600 from its first byte.
    virtual int create_truncated(const std::filesystem::path& path, FileAccess access) = 0;
    virtual void write_all(int handle, std::string_view bytes) = 0;
    virtual void flush(int handle) = 0;  // fsync
    virtual void close(int handle) = 0;
    virtual void rename(const std::filesystem::path& from, const std::filesystem::path& to) = 0;
    virtual void flush_directory(const std::filesystem::path& directory) = 0;
    virtual void remove(const std::filesystem::path& path) noexcept = 0;  // best effort
};

// The system's reason (errno) for a failed call, as an exception naming what failed and where:
// "cannot write /var/lib/calbox/x: No space left on device".
std::runtime_error os_error(const std::string& what, const std::filesystem::path& p);

// The POSIX calls (open, write, fsync, close, rename, fsync of the directory, unlink).
FileSystemCalls& posix_file_system();

// The sibling is `name` + ".tmp" in the same directory (a rename across directories is not
// atomic). On failure the sibling is removed and the old file is untouched.
void replace_file_durably(FileSystemCalls& fs, const std::filesystem::path& directory,
                          const std::string& name, std::string_view contents,
                          FileAccess access = FileAccess::shared);

}  // namespace calbox::drivers
