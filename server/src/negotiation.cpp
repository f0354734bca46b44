#include "negotiation.hpp"

#include <algorithm>

namespace tinstream::server {

bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return ascii_lower(x) == ascii_lower(y);
         });
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string_view next_item(std::string_view& rest, char sep) {
  const auto p = rest.find(sep);
  const std::string_view item = trim(rest.substr(0, p));
  rest = p == std::string_view::npos ? std::string_view() : rest.substr(p + 1);
  return item;
}

double accept_quality(std::string_view header, std::string_view coding) {
  double star = -1, exact = -1;
  any_item(header, ',', [&](std::string_view item) {
    if (item.empty()) return false;
    const std::string_view name = next_item(item, ';');
    double q = 1.0;
    any_item(item, ';', [&](std::string_view param) {
      if (param.size() > 2 && (param[0] == 'q' || param[0] == 'Q') && param[1] == '=') {
        try {
          q = std::stod(std::string(param.substr(2)));
        } catch (...) {
          q = 0;
        }
      }
      return false;
    });
    if (iequals(name, coding)) exact = q;
    if (name == "*") star = q;
    return false;
  });
  if (exact >= 0) return exact;
  if (star >= 0) return star;
  return 0;
}

bool accept_wants_extension(std::string_view accept, std::string_view ext) {
  return any_item(accept, ',', [&](std::string_view item) {
    const bool has_params = item.find(';') != std::string_view::npos;
    if (!iequals(next_item(item, ';'), "application/vnd.quantized-mesh") || !has_params)
      return false;
    return any_item(item, ';', [&](std::string_view param) {
      if (param.substr(0, 11) != "extensions=") return false;
      std::string_view list = param.substr(11);
      if (!list.empty() && list.front() == '"')
        list = list.substr(1, list.size() >= 2 ? list.size() - 2 : 0);
      return any_item(list, '-', [&](std::string_view e) { return e == ext; });
    });
  });
}

bool etag_matches(std::string_view if_none_match, std::string_view etag) {
  if (if_none_match.empty()) return false;
  return any_item(if_none_match, ',', [&](std::string_view tag) {
    if (tag == "*") return true;
    if (tag.substr(0, 2) == "W/") tag.remove_prefix(2);
    return tag == etag;
  });
}

std::string representation_etag(std::string_view etag, std::string_view suffix) {
  std::string tag(etag);
  if (suffix.empty()) return tag;
  const bool quoted = tag.size() >= 2 && tag.back() == '"';
  tag.insert(quoted ? tag.size() - 1 : tag.size(), std::string("-").append(suffix));
  return tag;
}

}  // namespace tinstream::server
