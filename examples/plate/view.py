# pvpython view.py: the fields of results/plate, their ranges, and the vertex data as gap.csv
import os
from paraview.simple import *

reader = Xdmf3ReaderS(FileName=[os.path.abspath("results/plate/solution.xdmf")])
reader.UpdatePipeline()
for name in reader.PointData.keys():
    print(name, reader.PointData[name].GetRange())
SaveData(os.path.abspath("gap.csv"), proxy=reader, PointDataArrays=["u1", "u2", "gap", "lambda"])
