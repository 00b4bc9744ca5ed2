"""Renders the last frame of an otmpm result file as ParaView would show it
with the user guide's steps (Xdmf3ReaderS, Points representation, coloured by
the magnitude of a field, colour bar) into a PNG (run with pvbatch).

    pvbatch paraview_render.py RESULT.xdmf FIELD OUT.png
"""
import sys

from paraview.simple import ColorBy, CreateView, SaveScreenshot, Show, Xdmf3ReaderS

xdmf, field, png = sys.argv[1:4]
reader = Xdmf3ReaderS(FileName=[xdmf])
view = CreateView("RenderView")
view.ViewSize = [800, 600]
view.ViewTime = reader.TimestepValues[-1]
view.OrientationAxesVisibility = 1
display = Show(reader, view)
display.SetRepresentationType("Points")
display.PointSize = 6
ColorBy(display, ("POINTS", field, "Magnitude"))
display.RescaleTransferFunctionToDataRange(True)
display.SetScalarBarVisibility(view, True)
view.ResetCamera()
SaveScreenshot(png, view, ImageResolution=[800, 600])
