#include "ropes_core/json_text.hpp"

#include "ropes_core/file_format_error.hpp"

namespace ropes::core {

using Json = nlohmann::json;

std::string parse_json(const std::string& text, Json* out) {
  bool too_deep = false;
  const Json::parser_callback_t limit = [&too_deep](int depth, Json::parse_event_t, Json&) {
    if (depth >= kMaxJsonDepth)  // depth counts from 0 at the outermost value
      too_deep = true;
    return !too_deep;
  };
  try {
    *out = Json::parse(text, limit);
  } catch (const Json::exception& e) {
    return std::string("is not JSON: ") + e.what();
  }
  if (too_deep)
    return "nests deeper than " + std::to_string(kMaxJsonDepth) + " levels";
  return "";
}

Json parse_json_or_discarded(const std::string& text) {
  Json value;
  if (!parse_json(text, &value).empty())
    return Json(Json::value_t::discarded);
  return value;
}

Json read_json_file(const std::filesystem::path& path, std::uint64_t max_bytes) {
  Json value;
  const std::string problem = parse_json(read_text_file(path, max_bytes), &value);
  if (!problem.empty())
    throw FileFormatError(path.string() + ": " + problem);
  return value;
}

Json read_json_file_if_present(const std::filesystem::path& path, std::uint64_t max_bytes) {
  if (!core::is_regular_file(path))
    return Json(Json::value_t::discarded);
  return parse_json_or_discarded(read_text_file(path, max_bytes));
}

std::string describe(const Json& v) {
  if (v.is_string()) {
    const std::string& text = v.get_ref<const std::string&>();
    return "\"" + text.substr(0, 40) + (text.size() > 40 ? "...\"" : "\"");
  }
  if (v.is_number_unsigned())
    return std::to_string(v.get<std::uint64_t>());
  if (v.is_number_integer())
    return std::to_string(v.get<std::int64_t>());
  if (v.is_number_float())
    return Json(v.get<double>()).dump();
  if (v.is_boolean())
    return v.get<bool>() ? "true" : "false";
  return std::string("a JSON ") + v.type_name();
}

std::string describe_sizes(const Json& v) {
  if (!v.is_array())
    return describe(v);
  std::string out = "[";
  for (std::size_t i = 0; i < v.size() && i < 8; ++i) {
    const Json& e = v[i];
    out += (i ? "," : "") +
           (e.is_number_unsigned() ? std::to_string(e.get<std::uint64_t>()) : std::string("?"));
  }
  return out + (v.size() > 8 ? ",...]" : "]");
}

}  // namespace ropes::core
