// The page's template filled in, for the server and for self-contained files.

#include "assets.h"

#include "chronomap/core/error.h"

namespace chronomap::viewer_assets {

namespace {

void replaceOnce(std::string& text, std::string_view mark, const std::string& with) {
  const size_t at = text.find(mark);
  if (at == std::string::npos) throw FormatError("viewer page: the mark " + std::string(mark) + " is missing");
  text.replace(at, mark.size(), with);
}

// Replaces every `from` with `to` (case-sensitively; both spellings are passed where needed).
std::string replaceAll(std::string_view text, std::string_view from, std::string_view to) {
  std::string out;
  out.reserve(text.size());
  size_t start = 0;
  for (size_t at = text.find(from); at != std::string_view::npos; at = text.find(from, start)) {
    out.append(text.substr(start, at - start));
    out.append(to);
    start = at + from.size();
  }
  out.append(text.substr(start));
  return out;
}

}  // namespace

std::string page(const std::string& script, const std::string& data) {
  std::string html(pageTemplate());
  replaceOnce(html, "<!--CHRONOMAP_DATA-->", data);
  replaceOnce(html, "<!--CHRONOMAP_SCRIPT-->", script);
  return html;
}

std::string scriptTag(const std::string& url) {
  std::string s = "<script src=\"";
  s.append(url).append("\"></script>");
  return s;
}

std::string inlineScript(std::string_view script) {
  // Inside a script element, "</script" would end it and "<!--" changes how the end is found;
  // in the bundle they can only stand in strings or regular expressions, where "\/" is "/" and
  // "\!" is "!".
  std::string body = replaceAll(script, "</script", "<\\/script");
  body = replaceAll(body, "</SCRIPT", "<\\/SCRIPT");
  body = replaceAll(body, "<!--", "<\\!--");
  std::string s = "<script>";
  s.append(body).append("</script>");
  return s;
}

std::string inlineData(const std::string& bytes) {
  std::string s = "<script type=\"application/octet-stream\" id=\"chronomap-data\">";
  s.append(base64(bytes)).append("</script>");
  return s;
}

}  // namespace chronomap::viewer_assets
