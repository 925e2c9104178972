"""The accuracy statement (output/accuracy.py) as ISO 19157 data-quality metadata in a
GeoPackage: the metadata extension's tables gpkg_metadata and gpkg_metadata_reference
(GeoPackage 1.2+, extension `gpkg_metadata`), one record in ISO 19157-2 XML referenced by
the whole GeoPackage and by its `points` layer.

The record is a DQ_DataQuality of the dataset with one DQ_AbsoluteExternalPositionalAccuracy
element per figure of the ASPRS Edition 2 statement: RMSE_H (ISO 19157 measure 47, root mean
square error of planimetry), RMSE_V and RMSE_3D (measure 39, root mean square error), each
with its evaluation method (direct external: the misses of independent check points) and two
results: the value in metres (DQ_QuantitativeResult) and the standard's sentence of the class
it was tested to meet (DQ_ConformanceResult).  Without a statement (fewer than 3 check
points) one DQ_DescriptiveResult says why.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from xml.sax.saxutils import escape

from baarda.output.accuracy import STANDARD, Statement

STANDARD_URI = "http://standards.iso.org/iso/19157/-2"
EXTENSION_URI = "http://www.geopackage.org/spec121/#extension_metadata"
METRE = "http://www.opengis.net/def/uom/EPSG/0/9001"
NS = ('xmlns:mdq="http://standards.iso.org/iso/19157/-2/mdq/1.0" '
      'xmlns:mcc="http://standards.iso.org/iso/19115/-3/mcc/1.0" '
      'xmlns:cit="http://standards.iso.org/iso/19115/-3/cit/1.0" '
      'xmlns:gco="http://standards.iso.org/iso/19115/-3/gco/1.0" '
      'xmlns:xlink="http://www.w3.org/1999/xlink" '
      'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"')
# (figure, ISO 19157 measure id, name of measure, what it measures)
ELEMENTS = (("rmse_h_m", "47", "root mean square error of planimetry",
             "RMSE_H = sqrt(RMSE_H1^2 + RMSE_H2^2): the horizontal (radial) RMSE of the check "
             "points' misses, RMSE_H1 = sqrt(RMSE_X^2 + RMSE_Y^2), combined with the check "
             "points' survey accuracy RMSE_H2"),
            ("rmse_v_m", "39", "root mean square error",
             "RMSE_V = sqrt(RMSE_V1^2 + RMSE_V2^2): the vertical RMSE of the check points' "
             "misses combined with their survey accuracy RMSE_V2"),
            ("rmse_3d_m", "39", "root mean square error",
             "RMSE_3D = sqrt(RMSE_H^2 + RMSE_V^2): three-dimensional positional accuracy"))


def _text(tag: str, value: str) -> str:
    return f"<{tag}><gco:CharacterString>{escape(value)}</gco:CharacterString></{tag}>"


def _citation(title: str) -> str:
    return f"<cit:CI_Citation>{_text('cit:title', title)}</cit:CI_Citation>"


def quality_xml(acc: Statement) -> str:
    """The statement as an ISO 19157-2 DQ_DataQuality document."""
    scope = ('<mdq:scope><mcc:MD_Scope><mcc:level><mcc:MD_ScopeCode codeList="http://standards'
             '.iso.org/iso/19115/resources/Codelists/cat/codelists.xml#MD_ScopeCode" '
             'codeListValue="dataset">dataset</mcc:MD_ScopeCode></mcc:level></mcc:MD_Scope>'
             '</mdq:scope>')
    method = ("<mdq:evaluationMethod><mdq:DQ_EvaluationMethod><mdq:evaluationMethodType>"
              '<mdq:DQ_EvaluationMethodTypeCode codeList="http://standards.iso.org/iso/19157/'
              'resources/Codelists/cat/codelists.xml#DQ_EvaluationMethodTypeCode" '
              'codeListValue="directExternal">directExternal</mdq:DQ_EvaluationMethodTypeCode>'
              "</mdq:evaluationMethodType>"
              + _text("mdq:evaluationMethodDescription",
                      f"{acc.n} independent check points compared with the adjusted "
                      "coordinates (adjusted - given), by " + STANDARD)
              + f"<mdq:evaluationProcedure>{_citation(STANDARD)}</mdq:evaluationProcedure>"
              "</mdq:DQ_EvaluationMethod></mdq:evaluationMethod>")
    reports = []
    if acc.stated:
        for (key, ident, name, what), sentence in zip(ELEMENTS, acc.sentences, strict=True):
            value = acc.figures[key]
            survey = acc.figures["rmse_h2_m" if key == "rmse_h_m" else "rmse_v2_m"]
            if key != "rmse_3d_m" and survey is None:
                what = what.split(":")[0] + ": the check points carry no survey accuracy, so " \
                    "this is their fit alone"
            measure = ("<mdq:measure><mdq:DQ_MeasureReference><mdq:measureIdentification>"
                       f"<mcc:MD_Identifier>{_text('mcc:code', ident)}"
                       f"{_text('mcc:codeSpace', 'ISO 19157')}</mcc:MD_Identifier>"
                       "</mdq:measureIdentification>" + _text("mdq:nameOfMeasure", name)
                       + _text("mdq:measureDescription", what)
                       + "</mdq:DQ_MeasureReference></mdq:measure>")
            quantity = (f'<mdq:result><mdq:DQ_QuantitativeResult><mdq:valueUnit xlink:href='
                        f'"{METRE}"/><mdq:value><gco:Record xsi:type="gco:Real_PropertyType">'
                        f"<gco:Real>{value:.6f}</gco:Real></gco:Record></mdq:value>"
                        "</mdq:DQ_QuantitativeResult></mdq:result>")
            conformance = ("<mdq:result><mdq:DQ_ConformanceResult><mdq:specification>"
                           f"{_citation(STANDARD)}</mdq:specification>"
                           + _text("mdq:explanation", sentence)
                           + "<mdq:pass><gco:Boolean>true</gco:Boolean></mdq:pass>"
                           "</mdq:DQ_ConformanceResult></mdq:result>")
            reports.append("<mdq:report><mdq:DQ_AbsoluteExternalPositionalAccuracy>"
                           + measure + method + quantity + conformance
                           + "</mdq:DQ_AbsoluteExternalPositionalAccuracy></mdq:report>")
    else:
        why = " ".join(acc.warnings) or "no check points"
        reports.append("<mdq:report><mdq:DQ_AbsoluteExternalPositionalAccuracy>" + method
                       + "<mdq:result><mdq:DQ_DescriptiveResult>"
                       + _text("mdq:statement", "No accuracy is stated: " + why)
                       + "</mdq:DQ_DescriptiveResult></mdq:result>"
                       "</mdq:DQ_AbsoluteExternalPositionalAccuracy></mdq:report>")
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<mdq:DQ_DataQuality {NS}>{scope}'
            + "".join(reports) + "</mdq:DQ_DataQuality>")


def write_quality_metadata(path: str | Path, acc: Statement, layer: str = "points") -> int:
    """Add the statement's record to the GeoPackage `path` (the metadata extension's tables
    created where missing and the extension registered); returns the record's id."""
    con = sqlite3.connect(str(path))
    try:
        with con:
            con.execute(
                "CREATE TABLE IF NOT EXISTS gpkg_metadata (id INTEGER CONSTRAINT m_pk PRIMARY "
                "KEY ASC NOT NULL, md_scope TEXT NOT NULL DEFAULT 'dataset', md_standard_uri "
                "TEXT NOT NULL, mime_type TEXT NOT NULL DEFAULT 'text/xml', metadata TEXT NOT "
                "NULL DEFAULT '')")
            con.execute(
                "CREATE TABLE IF NOT EXISTS gpkg_metadata_reference (reference_scope TEXT NOT "
                "NULL, table_name TEXT, column_name TEXT, row_id_value INTEGER, timestamp "
                "DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')), md_file_id "
                "INTEGER NOT NULL, md_parent_id INTEGER, CONSTRAINT crmr_mfi_fk FOREIGN KEY "
                "(md_file_id) REFERENCES gpkg_metadata(id), CONSTRAINT crmr_mpi_fk FOREIGN KEY "
                "(md_parent_id) REFERENCES gpkg_metadata(id))")
            con.execute(
                "CREATE TABLE IF NOT EXISTS gpkg_extensions (table_name TEXT, column_name TEXT, "
                "extension_name TEXT NOT NULL, definition TEXT NOT NULL, scope TEXT NOT NULL, "
                "CONSTRAINT ge_tce UNIQUE (table_name, column_name, extension_name))")
            for table in ("gpkg_metadata", "gpkg_metadata_reference"):
                con.execute("INSERT OR IGNORE INTO gpkg_extensions VALUES (?, NULL, "
                            "'gpkg_metadata', ?, 'read-write')", (table, EXTENSION_URI))
            cur = con.execute("INSERT INTO gpkg_metadata (md_scope, md_standard_uri, "
                              "mime_type, metadata) VALUES ('dataset', ?, 'text/xml', ?)",
                              (STANDARD_URI, quality_xml(acc)))
            md = cur.lastrowid
            assert md is not None  # the row just inserted
            con.execute("INSERT INTO gpkg_metadata_reference (reference_scope, table_name, "
                        "md_file_id) VALUES ('geopackage', NULL, ?)", (md,))
            con.execute("INSERT INTO gpkg_metadata_reference (reference_scope, table_name, "
                        "md_file_id) VALUES ('table', ?, ?)", (layer, md))
    finally:
        con.close()
    return md
