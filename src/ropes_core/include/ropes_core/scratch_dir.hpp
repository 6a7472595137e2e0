#pragma once
/// @file scratch_dir.hpp
/// ScratchDir: a private temporary folder for a test or a fuzz harness, gone with the object.
#include <stdlib.h>  // mkdtemp

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

namespace ropes::core {

/// A folder of its own (under $TMPDIR or /tmp, named PREFIX-XXXXXX by mkdtemp), removed with
/// everything in it when the object goes. Tests keep one per fixture; fuzz harnesses keep
/// one in a function-local static and clear() it per input.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& prefix = "ropes-fuzz") {
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern =
        std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/" + prefix + "-XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr)
      throw std::runtime_error("cannot create a scratch folder from " + pattern);
    root_ = pattern;
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(root_, ec);
  }

  const std::filesystem::path& path() const { return root_; }

  /// Removes everything inside the folder.
  void clear() const {
    for (const auto& entry : std::filesystem::directory_iterator(root_))
      std::filesystem::remove_all(entry.path());
  }

  /// Writes `bytes` to path() / relative (creating its folders) and returns the full path.
  /// `relative` comes from the harness, never from the input.
  std::filesystem::path write(const std::string& relative, const std::string& bytes) const {
    const std::filesystem::path file = root_ / relative;
    std::filesystem::create_directories(file.parent_path());
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out)
      throw std::runtime_error("cannot write " + file.string());
    return file;
  }

 private:
  std::filesystem::path root_;
};

}  // namespace ropes::core
