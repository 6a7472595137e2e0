#pragma once
/// @file fuzz_input.hpp
/// What the workspace's libFuzzer harnesses share (fuzz/ in each package, RopesFuzz.cmake):
/// one input split into several named files, a private scratch folder to write them to, and
/// the rule for what a reader may do with bad input.
///
/// A reader given bad input must throw one of its documented errors, all std::runtime_error
/// (FileFormatError, ConfigError, ModelError, MeshError, DdsError); a harness catches those
/// and nothing else. Anything else escaping — std::bad_alloc, a std::logic_error such as
/// std::length_error or std::out_of_range, a JSON library exception that was not turned into
/// a message naming the file — is a finding: the harness lets it escape, libFuzzer reports
/// the input, and the input goes to fuzz/regressions/ once fixed.
#include "ropes_core/scratch_dir.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace ropes::core::fuzz {

/// One named part of a multi-file input.
struct Section {
  std::string name;   ///< "" for the bytes before the first marker
  std::string bytes;  ///< the part's content
};

/// Splits an input into sections. A line "==> NAME <==" (NAME without spaces) starts the
/// section NAME; the bytes before the first such line are the section "" (kept even when
/// empty, so the first section is always the main file). The newline before a marker line
/// belongs to the marker, so join_sections(split_sections(x)) == x for every x it makes.
/// Corpus files are mostly text this way, and libFuzzer's mutations keep their structure.
inline std::vector<Section> split_sections(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<Section> out(1);
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t eol = text.find('\n', pos);
    const std::size_t end = eol == std::string::npos ? text.size() : eol;
    const std::string line = text.substr(pos, end - pos);
    const bool marker = line.size() > 8 && line.compare(0, 4, "==> ") == 0 &&
                        line.compare(line.size() - 4, 4, " <==") == 0 &&
                        line.find(' ', 4) == line.size() - 4;
    if (marker) {
      if (!out.back().bytes.empty())
        out.back().bytes.pop_back();  // the newline before the marker
      out.push_back({line.substr(4, line.size() - 8), ""});
    } else {
      out.back().bytes += text.substr(pos, (eol == std::string::npos ? end : end + 1) - pos);
    }
    if (eol == std::string::npos)
      break;
    pos = eol + 1;
  }
  return out;
}

/// The input split_sections() splits into `sections` (the first one's name is not written):
/// how a corpus file is made from real files.
inline std::string join_sections(const std::vector<Section>& sections) {
  std::string out;
  for (std::size_t i = 0; i < sections.size(); ++i) {
    if (i > 0)
      out += "\n==> " + sections[i].name + " <==\n";
    out += sections[i].bytes;
  }
  return out;
}

/// fuzz harnesses name it in their own namespace
using core::ScratchDir;

}  // namespace ropes::core::fuzz
